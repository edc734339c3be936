"""The layout stage: luminaires in metres and the room they light, read from drawings and tables."""
