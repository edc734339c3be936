"""The camera: its model (intrinsics, lens, rolling shutter), lens projections, camera files and LED ellipse images."""
