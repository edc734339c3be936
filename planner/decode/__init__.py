"""The phone image decoder: a camera frame to LED blobs, ellipses, chips and IDs (used by the twin, photos and locate alike)."""
