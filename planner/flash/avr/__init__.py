"""Emulated AVR drivers: the reference firmware (firmware_templates/driver/) on simavr, behind a pseudo-terminal.

:mod:`.build` compiles the firmware and the simavr harness, :mod:`.runner` runs N emulated
MCUs on one shared line with persisted EEPROMs and LED traces, and :mod:`.trace` reads the
light back from a trace. docs/firmware.md ("Reference driver firmware") describes them.
"""
