"""Per-luminaire firmware artifacts: the configuration header, JSON and binary image."""
