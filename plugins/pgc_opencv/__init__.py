"""opencv plugin for PGC. Keep this file light (no opencv import)."""
