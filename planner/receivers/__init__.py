"""Receiver modes: how a phone tells where it is from the LEDs it sees."""
