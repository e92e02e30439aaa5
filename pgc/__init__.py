"""PGC: physics-based Gaussian cloth from a single pose.

``import pgc`` is light (numpy, pluggy, pydantic at most); array libraries load only when an
implementation that needs them is built. Importing it holds OpenBLAS to one thread
(:func:`pgc.cores.keep_blas_single_threaded`).
"""

from pgc.cores import keep_blas_single_threaded

keep_blas_single_threaded()

__version__ = "0.1.0"
