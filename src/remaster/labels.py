"""How sensors are named and ordered in tables and figures, shared by the analyses that build
tables and the reporting that draws them (so that neither imports the other)."""

from __future__ import annotations

SENSOR_LABELS = {"motion_capture": "Motion Capture", "laser_tracker": "Laser Tracker"}


def sensor_label(name: str) -> str:
    """A sensor's display name: the paper's for its two sensors, the title-cased name otherwise."""
    return SENSOR_LABELS.get(name, name.replace("_", " ").title())


def paper_order(sensors) -> list[str]:
    """Sensors in the paper's column order (motion capture, laser tracker), then the others by name."""
    known = list(SENSOR_LABELS)
    return sorted(sensors, key=lambda s: (known.index(s) if s in known else len(known), s))
