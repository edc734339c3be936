"""Modulation: the frame (preamble, line code), frames over several exposures and the chip rate a camera reads."""
