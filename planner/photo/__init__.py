"""Real photos in: read a phone photo of the ceiling, decode every LED blob, locate, check the as-built IDs."""
