"""fuzzyservo.fuzzy."""
