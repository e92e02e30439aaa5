"""The one helper of this backend for torch's intra-op thread count."""

from __future__ import annotations

import contextlib
from typing import Iterator


@contextlib.contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """Run with ``n`` torch intra-op threads (0: unchanged), restoring the previous count afterwards.

    The backend's per-Gaussian and per-constraint tensors are small: one thread avoids OpenMP barriers that cost
    far more than they gain on a busy 2-core machine; the compiled kernels keep their own OpenMP threads.
    """
    import torch

    previous = torch.get_num_threads()
    if n:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
