"""Identification of the servo model from measured data (issue 27)."""
