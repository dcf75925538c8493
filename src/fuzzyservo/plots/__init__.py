"""fuzzyservo.plots."""
