"""Testing kit for plugin authors: an isolated registry fixture and per-role conformance suites."""
