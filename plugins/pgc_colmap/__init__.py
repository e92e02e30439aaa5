"""colmap plugin for PGC. Keep this file light (no colmap import)."""
