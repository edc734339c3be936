"""Flashing luminaire drivers over a serial link: wire format, driver simulator, host flasher."""
