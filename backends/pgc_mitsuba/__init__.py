"""Mitsuba 3 / Dr.Jit backend: BRDFs as Mitsuba BSDFs, path-traced PBR rendering and material fitting.

Keep this file light (no mitsuba import); use :mod:`pgc_mitsuba.runtime` to import Mitsuba.
"""
