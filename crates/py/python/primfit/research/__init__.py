"""The research harness of thesis chapter 5: learning existence with a network.

Not part of the fitting API (``primfit``); these modules reproduce and extend the
thesis's nine-cylinder experiments on top of it. Import the one you need; nothing is
imported here, because :mod:`~primfit.research.nn` and :mod:`~primfit.research.train`
need the optional torch.

* :mod:`primfit.research.nine`: the nine-cylinder scenes (clouds, masks, chamfer problems).
* :mod:`primfit.research.nn`: the existence networks (PointNet++, candidate-local).
* :mod:`primfit.research.train`: training and scoring; ``python -m primfit.research.train``.
* :mod:`primfit.research.experiments`: Table 5.1 and the offset sweep;
  ``python -m primfit.research.experiments --out results/``.
"""
