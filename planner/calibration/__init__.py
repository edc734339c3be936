"""Camera calibration: intrinsics and distortion from chessboard photos, the rolling shutter's row time from a
blinking LED, and that LED's test firmware (``vlp-calibrate``)."""
