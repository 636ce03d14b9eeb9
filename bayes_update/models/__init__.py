"""Models shipped with the framework.  Each is a model of the contract
(:mod:`bayes_update.core.model`) or an adapter that makes one:

* :mod:`.beam`: the preloaded beam of Bussetta, Shiki and da Silva (2017),
  ``fe.BeamModel`` and ``fe.ModalROM``, with its P_eff coordinates, paper
  units, effects catalogue and the paper's grids.
* :mod:`.modal`: modes in superposition with nonlinear elements (``ModalModel``).
"""
