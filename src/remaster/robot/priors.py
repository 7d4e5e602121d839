"""Gaussian priors of the extension blocks: the size of a manufacturing or mounting tolerance.

The paper's blocks (registration, zero-offsets) keep the paper's flat prior and sigma its
Jeffreys prior. Every parameter an extension block adds gets N(0, std^2) about the nominal,
std from `config.yaml` (`priors:`), one set of tolerances per class of arm, overridable per
campaign in campaign.yaml (`robot.priors`, same keys and units). With priors the extended
model has a proper posterior and a Laplace evidence, and a parameter the data barely move keeps
its prior width, which then shows in the workspace-wide accuracy (docs/methods.md, "Priors").

Keys are in display units (the config is read by people); `Priors.std_of` gives SI.
`held_zero_offset_deg` is the tolerance of the controller's marks (Vernier scales) on a
zero-offset no sensor can see (joint 1 against a free registration): used only where an
accuracy is stated in the robot's own frame.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from ..errors import InputError, quoted
from ..units import SECONDS_PER_HOUR

DEG = math.pi / 180.0
MM = 1e-3
MICRO = 1e-6

# config key: (SI size of one display unit, what it is the std of)
KEYS = {
    "link_translation_mm": (
        MM,
        "translation error of each fixed link transform, per axis of its frame (link_geometry.*.x/y/z)",
    ),
    "link_rotation_deg": (
        DEG,
        "rotation error of each fixed link transform, per axis of its frame (link_geometry.*.rx/ry/rz)",
    ),
    "marker_offset_mm": (MM, "marker position error per axis, flange frame (marker_offset.*)"),
    "joint_compliance_urad_per_Nm": (MICRO, "compliance of each joint and its payload term (joint_compliance.*)"),
    "joint_scale_ppm": (MICRO, "scale (gear-ratio) error of each joint reading (joint_scale.*)"),
    "joint_scale_output_ppm": (
        MICRO,
        "scale error of each joint reading where the encoders read the joint's output, after the gear "
        "(joint_scale.*, robot/joint_encoders: output)",
    ),
    "sensor_scale_ppm": (MICRO, "scale error of the sensor's lengths (sensor_scale.s)"),
    "sensor_distortion_ppm": (
        MICRO,
        "each coefficient of the sensor frame's symmetric traceless distortion (sensor_distortion.*)",
    ),
    "drift_deg_per_hour": (DEG / SECONDS_PER_HOUR, "zero-offset drift rate per hour of elapsed time (drift.*)"),
    "drift_deg_per_kelvin": (DEG, "zero-offset drift per kelvin of temperature change (drift.*)"),
    "joint_harmonic_deg": (
        DEG,
        "each Fourier coefficient of a joint's cyclic error, a_jk cos(k q_j) + b_jk sin(k q_j) (joint_harmonics.*)",
    ),
    "held_zero_offset_deg": (DEG, "controller marks' tolerance on a zero-offset no sensor can see (robot frame)"),
}
CLASS_KEY = "arm_class"
CLASSES = ("industrial", "collaborative")
# How the arm reads its joints (campaign.yaml robot/joint_encoders): on the motor, before the gear,
# a reading's scale is the gear ratio's error (joint_scale_ppm, today's default and the unknown
# case); at the output, after the gear (Universal Robots, KUKA LBR iiwa), the encoder reads the
# joint's angle itself and its scale is the encoder's graduation (joint_scale_output_ppm)
ENCODERS_KEY = "joint_encoders"
JOINT_ENCODERS = ("motor", "output")


@dataclass(frozen=True)
class Priors:
    """Prior standard deviations in display units ({KEYS key: value}) of one class of arm,
    after any campaign override; `source` says where they came from."""

    arm_class: str
    values: dict[str, float]
    source: str = "config"
    joint_encoders: str = "motor"

    def std(self, key: str) -> float:
        """SI std of one key."""
        return float(self.values[key]) * KEYS[key][0]

    def std_of(self, name: str, drift_unit: str | None = None) -> float:
        """SI prior std of a model parameter by name; inf (flat) for the paper's parameters."""
        block = name.split(".", 1)[0]
        if block in ("registration", "zero_offsets", "noise"):
            return math.inf
        if block == "link_geometry":
            return self.std("link_rotation_deg" if name.rsplit(".", 1)[-1].startswith("r") else "link_translation_mm")
        if block == "drift":
            return self.std("drift_deg_per_kelvin" if drift_unit == "K" else "drift_deg_per_hour")
        key = {
            "marker_offset": "marker_offset_mm",
            "joint_compliance": "joint_compliance_urad_per_Nm",
            "joint_scale": "joint_scale_output_ppm" if self.joint_encoders == "output" else "joint_scale_ppm",
            "sensor_scale": "sensor_scale_ppm",
            "joint_harmonics": "joint_harmonic_deg",
            "sensor_distortion": "sensor_distortion_ppm",
        }.get(block)
        if key is None:
            raise ValueError(f"no prior for parameter {name!r}")
        return self.std(key)

    def report(self) -> dict:
        return {
            "arm_class": self.arm_class,
            "source": self.source,
            "joint_encoders": self.joint_encoders,
            "std_display_units": dict(self.values),
            "meaning": {k: text for k, (_, text) in KEYS.items()},
        }


def _checked_values(values: Mapping, where: str, source: str) -> dict[str, float]:
    out = {}
    for key, value in values.items():
        if key == CLASS_KEY:
            continue
        if key not in KEYS:
            raise InputError(
                f"unknown prior; allowed: {CLASS_KEY}, {', '.join(KEYS)}", file=source, key=f"{where}/{key}"
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
            raise InputError(
                f"must be a positive number (a standard deviation in the unit its name gives), got {quoted(value)}",
                file=source,
                key=f"{where}/{key}",
            )
        out[key] = float(value)
    return out


def check_override(override, source: str) -> None:
    """Refuse a campaign's `robot.priors` that is not {arm_class?, KEYS key: positive number}."""
    if not isinstance(override, Mapping):
        raise InputError(f"must be a mapping of priors, got {quoted(override)}", file=source, key="robot/priors")
    arm_class = override.get(CLASS_KEY)
    if arm_class is not None and arm_class not in CLASSES:
        raise InputError(
            f"must be one of {', '.join(CLASSES)}, got {quoted(arm_class)}",
            file=source,
            key=f"robot/priors/{CLASS_KEY}",
        )
    _checked_values(override, "robot/priors", source)


def check_encoders(value, source: str) -> str:
    """A campaign's `robot.joint_encoders`: one of JOINT_ENCODERS, else an InputError naming the key."""
    if not isinstance(value, str) or value not in JOINT_ENCODERS:
        raise InputError(
            f"must be one of {', '.join(JOINT_ENCODERS)} (where the encoders read the joint: on the motor, before "
            f"the gear, or at the joint's output), got {quoted(value)}",
            file=source,
            key=f"robot/{ENCODERS_KEY}",
        )
    return value


def priors_from(config: Mapping, campaign_robot: Mapping | None = None, source: str = "campaign.yaml") -> Priors:
    """The priors of one campaign: the config's class (or the campaign's `robot.priors.arm_class`),
    then the campaign's own values over it, and the joint scale's by its `robot.joint_encoders`
    (motor when it does not say). config: the workflow's `priors` section."""
    encoders = check_encoders((campaign_robot or {}).get(ENCODERS_KEY, "motor"), source)
    override = (campaign_robot or {}).get("priors")
    if override is not None:
        check_override(override, source)
    override = dict(override or {})
    arm_class = override.get(CLASS_KEY) or config.get(CLASS_KEY)
    if arm_class not in CLASSES:  # a campaign's class is checked above: this one is the config's
        raise InputError(
            f"must be one of {', '.join(CLASSES)}, got {quoted(arm_class)}", file="config", key=f"priors/{CLASS_KEY}"
        )
    if not isinstance(config.get(arm_class), Mapping):
        raise InputError(
            f"must be a mapping of priors, got {quoted(config.get(arm_class))}",
            file="config",
            key=f"priors/{arm_class}",
        )
    values = _checked_values(config[arm_class], f"priors/{arm_class}", "config")
    missing = [k for k in KEYS if k not in values]
    if missing:
        raise InputError(f"missing priors {', '.join(missing)}", file="config", key=f"priors/{arm_class}")
    own = _checked_values(override, "robot/priors", source)
    return Priors(arm_class, {**values, **own}, "config" if not own else f"config, overridden by {source}", encoders)


# Defaults (config.yaml repeats them with their reasons; these serve library calls without a config).
DEFAULTS = {
    CLASS_KEY: "collaborative",
    "industrial": {
        "link_translation_mm": 1.0,
        "link_rotation_deg": 0.1,
        "marker_offset_mm": 1.0,
        "joint_compliance_urad_per_Nm": 50.0,
        "joint_scale_ppm": 1000.0,
        "joint_scale_output_ppm": 30.0,
        "sensor_scale_ppm": 500.0,
        "sensor_distortion_ppm": 1000.0,
        "drift_deg_per_hour": 0.05,
        "drift_deg_per_kelvin": 0.02,
        "joint_harmonic_deg": 0.02,
        "held_zero_offset_deg": 0.5,
    },
    "collaborative": {
        "link_translation_mm": 1.0,
        "link_rotation_deg": 0.1,
        "marker_offset_mm": 1.0,
        "joint_compliance_urad_per_Nm": 200.0,
        "joint_scale_ppm": 1000.0,
        "joint_scale_output_ppm": 30.0,
        "sensor_scale_ppm": 500.0,
        "sensor_distortion_ppm": 1000.0,
        "drift_deg_per_hour": 0.05,
        "drift_deg_per_kelvin": 0.02,
        "joint_harmonic_deg": 0.02,
        "held_zero_offset_deg": 0.5,
    },
}


def with_defaults(config: Mapping | None) -> dict:
    """The config's `priors` section laid over DEFAULTS, class by class, key by key."""
    config = dict(config or {})
    out = {CLASS_KEY: config.get(CLASS_KEY, DEFAULTS[CLASS_KEY])}
    for arm_class in CLASSES:
        out[arm_class] = {**DEFAULTS[arm_class], **dict(config.get(arm_class) or {})}
    return out
