"""PGC: physics-based Gaussian cloth from a single pose.

``import pgc`` is light (numpy, pluggy, pydantic at most); array libraries load only when an
implementation that needs them is built.
"""

__version__ = "0.1.0"
