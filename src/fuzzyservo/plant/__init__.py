"""fuzzyservo.plant."""
