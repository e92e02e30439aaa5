"""open3d plugin for PGC. Keep this file light (no open3d import)."""
