"""fuzzyservo.analysis."""
