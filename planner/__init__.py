"""vlp-plan: LED-ID planning for camera-based visible light positioning."""

__version__ = "0.1.0"
