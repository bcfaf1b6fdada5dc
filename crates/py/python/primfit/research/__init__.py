"""The research harness of thesis chapter 5: learning existence with a network.

Not part of the fitting API (``primfit``); these modules reproduce and extend the
thesis's nine-cylinder experiments on top of it. Import the one you need; nothing is
imported here, because :mod:`~primfit.research.nn` and :mod:`~primfit.research.train`
need the optional torch.

* :mod:`primfit.research.nine`: the nine-cylinder scenes (clouds, masks, chamfer problems).
* :mod:`primfit.research.nn`: the existence networks (PointNet++, candidate-local).
* :mod:`primfit.research.train`: training and scoring; ``python -m primfit.research.train``.
* :mod:`primfit.research.experiments`: Table 5.1 and the offset sweep;
  ``python -m primfit.research.experiments table --out results/``; and ``evaluate``,
  the scores of a shipped network on fresh held-out scenes.
* :mod:`primfit.research.pretrained`: the shipped networks (:func:`load_pretrained`)
  and the command that trains them.
* :mod:`primfit.research.evaluate`: held-out scenes and scores.
* :mod:`primfit.research.warm_start`: a network's existence as the start of the
  chamfer solver.
"""

from __future__ import annotations

from typing import Any

__all__ = ["load_pretrained"]


def load_pretrained(name: str) -> Any:
    """The shipped existence network ``name`` (``"pointnet2"`` or ``"local"``), a
    ``torch.nn.Module`` in eval mode; see :func:`primfit.research.pretrained.load_pretrained`
    (needs torch)."""
    from .pretrained import load_pretrained as load

    return load(name)
