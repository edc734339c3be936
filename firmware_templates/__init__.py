"""The bundled firmware templates (``*.j2``), installed as ``planner.firmware_templates``.

A package only so that setuptools ships the folder; ``planner.firmware.render`` finds it with
importlib.resources, or in the source tree next to ``planner/``. docs/firmware.md
lists the variables the templates see.
"""
