"""Data files shipped in the package (LPIPS AlexNet weights with their provenance record)."""
