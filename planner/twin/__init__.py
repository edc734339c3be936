"""The receiver twin: render what a phone camera captures, decode it like a receiver app, locate."""
