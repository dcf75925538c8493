"""fuzzyservo.identify: the servo model identified from measured data (issue 27)."""
