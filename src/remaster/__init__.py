"""remaster: Bayesian in-situ remastering of robot joint zero-offsets.

The Python interface is `remaster.api` (`calibrate`, `predict`, `compensate`, `compare`,
`settings`), also reachable from here (`remaster.calibrate`, ...): imported on first use, so that
`import remaster` stays light.
"""

__version__ = "0.1.0"
DISTRIBUTION = "remaster-robot"  # pyproject.toml's name: `remaster` on the package index is another project
API = ("Calibration", "calibrate", "compare", "compensate", "predict", "settings")
__all__ = ["__version__", *API]


def __getattr__(name: str):
    if name in API:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'remaster' has no attribute {name!r}")
