"""fuzzyservo.control."""
