"""Simulated luminaire drivers: the driver state machine, its flash, a multi-drop bus, the ``sim://`` URL."""
