"""The ten ``vlp-*`` commands: one module each, and their shared parser and conventions (``common``)."""
