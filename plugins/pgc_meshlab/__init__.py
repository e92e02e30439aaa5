"""meshlab plugin for PGC. Keep this file light (no meshlab import)."""
