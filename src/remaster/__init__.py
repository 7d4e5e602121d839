"""remaster: Bayesian in-situ remastering of robot joint zero-offsets."""

__version__ = "0.1.0"
