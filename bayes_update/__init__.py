"""bayes_update: probabilistic updating of the nonlinear FE model of the
preloaded-beam rig with Volterra series (after Bussetta, Shiki and da Silva, 2017)."""

__version__ = "0.1.0"
