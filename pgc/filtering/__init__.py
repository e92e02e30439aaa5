"""Kernel sizing for the alpha-aware low-pass (the ``filter`` role) and its automatic choice.

Light: numpy, scipy and pydantic only. Backends implement the blur; this package sizes it.
"""

from pgc.filtering.auto import (KernelChoice, KernelSelection, candidate_sizes, choose_kernel_by_error,
                                choose_kernel_by_gradient, choose_kernel_by_metric, gradient_magnitude, hybrid_error,
                                hybrid_score, select_kernel, smallest_within, TrainingFrame)
from pgc.filtering.kernel import (PAPER_IMAGE_HEIGHT, PAPER_KERNEL_SIZE, gaussian_kernel_1d,
                                  kernel_size_for_height, odd_size)

__all__ = ["KernelChoice", "KernelSelection", "candidate_sizes", "choose_kernel_by_error",
           "choose_kernel_by_gradient", "choose_kernel_by_metric", "gradient_magnitude", "hybrid_error",
           "hybrid_score", "select_kernel", "smallest_within", "TrainingFrame", "PAPER_IMAGE_HEIGHT", "PAPER_KERNEL_SIZE",
           "gaussian_kernel_1d", "kernel_size_for_height", "odd_size"]
