"""fuzzyservo.paper."""
