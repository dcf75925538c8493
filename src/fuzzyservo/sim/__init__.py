"""fuzzyservo.sim."""
