"""remaster: Bayesian in-situ remastering of robot joint zero-offsets."""

__version__ = "0.1.0"
DISTRIBUTION = "remaster-robot"  # pyproject.toml's name: `remaster` on the package index is another project
