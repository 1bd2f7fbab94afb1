"""Dense layers on the CPU through oneDNN where torch has it: the matrix products of the
surrogate networks' fast inference paths (:mod:`.models`, :mod:`.sequence`)."""

from __future__ import annotations

import torch
from torch import nn

#: whether torch has oneDNN's fused linear op (private to torch, pinned to 2.13)
ONEDNN = torch.backends.mkldnn.is_available() and hasattr(torch.ops.mkldnn, "_linear_pointwise")


def linear(x: torch.Tensor, w: torch.Tensor, b: torch.Tensor | None = None) -> torch.Tensor:
    """x W^T + b for 2-D float32 ``x``, through oneDNN where torch has it (the op torch's
    Inductor compiles CPU linear layers to), else torch.nn.functional.linear (MKL). For these
    thin matrices oneDNN measured about twice MKL's FLOP rate on the bench machine (AMD EPYC,
    where MKL seems to run its AVX2 kernels). The op is private to torch (pinned to 2.13): where it
    is missing, ``ONEDNN`` is false and the torch path is taken."""
    if ONEDNN and x.dtype == torch.float32:
        return torch.ops.mkldnn._linear_pointwise(x, w, b, "none", [], "")
    return nn.functional.linear(x, w, b)


def linear_add(x: torch.Tensor, w: torch.Tensor, other: torch.Tensor) -> torch.Tensor:
    """other + x W^T (a new tensor), fused by oneDNN where available (see :func:`linear`)."""
    if ONEDNN and x.dtype == torch.float32:
        return torch.ops.mkldnn._linear_pointwise.binary(x, other, w, None, "add")
    return torch.addmm(other, x, w.t())
