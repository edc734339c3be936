"""The assignment stage: an ID for every luminaire (the paper's region code, window codes, check bits)."""
