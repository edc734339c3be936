"""Positioning: a receiver's position from the LED ellipses it sees (the paper's method and full perspective)."""
