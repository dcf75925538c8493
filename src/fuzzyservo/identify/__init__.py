"""fuzzyservo.identify: identify the servo model from measured data."""
