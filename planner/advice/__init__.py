"""Site advice: what would make a site work (camera, height, density, receiver, frame length)."""
