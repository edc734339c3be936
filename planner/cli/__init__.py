"""The eleven ``vlp-*`` commands: one module each, their one parser builder and shared flags (``common``) and how they run (``console``)."""
