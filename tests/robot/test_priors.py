"""Priors of the loop closure's extension blocks (remaster.robot.priors): SI standard deviations from
config.yaml's `priors:` section, the class of arm, a campaign's own `robot.priors`, and every bad
prior refused with its file and key (docs/bad-input.md)."""

from __future__ import annotations

import copy
import math
import shutil

import pytest
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from remaster import files
from remaster.campaigns import folders
from remaster.errors import InputError
from remaster.robot.priors import CLASSES, DEFAULTS, JOINT_ENCODERS, KEYS, priors_from, with_defaults

from ..conftest import REPO

CONFIG = files.read_yaml(REPO / "config.yaml")
SECTION = CONFIG["priors"]
SCHEMA = str(REPO / "src" / "remaster" / "data" / "config.schema.yaml")
TWIN = REPO / "data" / "raw" / "kuka-twin"
SENSOR = "laser_tracker"
ALLOWED = (
    "allowed: arm_class, link_translation_mm, link_rotation_deg, marker_offset_mm, joint_compliance_urad_per_Nm, "
    "joint_scale_ppm, joint_scale_output_ppm, sensor_scale_ppm, sensor_distortion_ppm, drift_deg_per_hour, drift_deg_per_kelvin, joint_harmonic_deg, "
    "held_zero_offset_deg"
)
POSITIVE = "must be a positive number (a standard deviation in the unit its name gives), got "

# A hand-written section with round numbers, so the SI answers below are known without the code.
KNOWN = {
    "arm_class": "industrial",
    "industrial": {
        "link_translation_mm": 1.0,
        "link_rotation_deg": 0.1,
        "marker_offset_mm": 2.0,
        "joint_compliance_urad_per_Nm": 50,
        "joint_scale_ppm": 1000,
        "joint_scale_output_ppm": 30,
        "sensor_scale_ppm": 500,
        "sensor_distortion_ppm": 1000,
        "drift_deg_per_hour": 0.36,
        "drift_deg_per_kelvin": 0.02,
        "joint_harmonic_deg": 0.02,
        "held_zero_offset_deg": 0.5,
    },
    "collaborative": {
        "link_translation_mm": 1.0,
        "link_rotation_deg": 0.1,
        "marker_offset_mm": 2.0,
        "joint_compliance_urad_per_Nm": 200,
        "joint_scale_ppm": 1000,
        "joint_scale_output_ppm": 30,
        "sensor_scale_ppm": 500,
        "sensor_distortion_ppm": 1000,
        "drift_deg_per_hour": 0.36,
        "drift_deg_per_kelvin": 0.02,
        "joint_harmonic_deg": 0.02,
        "held_zero_offset_deg": 0.5,
    },
}


def section(arm_class: str | None = None, **changes) -> dict:
    """config.yaml's priors section, with `changes` ({class: {key: value}}) laid over it."""
    out = copy.deepcopy(SECTION)
    if arm_class is not None:
        out["arm_class"] = arm_class
    for name, values in changes.items():
        out[name].update(values)
    return out


# --------------------------------------------------------------------------- SI values


def test_std_of_gives_si_values_of_known_priors():
    priors = priors_from(KNOWN)
    assert priors.arm_class == "industrial" and priors.source == "config"
    expected = {
        "link_geometry.F2.x": 1e-3,  # 1 mm
        "link_geometry.tool.z": 1e-3,
        "link_geometry.F2.rx": 0.1 * math.pi / 180,  # 0.1 deg = 1.745e-3 rad
        "link_geometry.tool.rz": 1.7453292519943296e-3,
        "marker_offset.x": 2e-3,  # 2 mm
        "marker_offset.z": 2e-3,
        "joint_compliance.q3": 50e-6,  # 50 urad/(N m)
        "joint_compliance.payload_q3": 50e-6,
        "joint_scale.q7": 1e-3,  # 1000 ppm
        "sensor_scale.s": 5e-4,  # 500 ppm
    }
    for name, value in expected.items():
        assert priors.std_of(name) == pytest.approx(value, rel=1e-12), name
    assert priors.std("held_zero_offset_deg") == pytest.approx(math.radians(0.5), rel=1e-12)


def test_drift_prior_follows_the_drift_unit():
    priors = priors_from(KNOWN)
    # per kelvin: 0.02 deg/K = 3.49e-4 rad/K
    assert priors.std_of("drift.q2", "K") == pytest.approx(0.02 * math.pi / 180, rel=1e-12)
    # per time (seconds, or no unit given): 0.36 deg/h = 1e-4 deg/s = 1.745e-6 rad/s
    for unit in ("s", None):
        assert priors.std_of("drift.q2", unit) == pytest.approx(1.7453292519943296e-6, rel=1e-12)


def test_std_of_the_configs_section_in_si():
    """The same conversions on config.yaml's own section (class as configured)."""
    priors = priors_from(SECTION)
    values = SECTION[SECTION["arm_class"]]
    assert priors.arm_class == SECTION["arm_class"] and priors.values == pytest.approx(values)
    assert priors.std_of("link_geometry.F1.y") == pytest.approx(values["link_translation_mm"] / 1000)
    assert priors.std_of("link_geometry.F1.ry") == pytest.approx(math.radians(values["link_rotation_deg"]))
    assert priors.std_of("marker_offset.y") == pytest.approx(values["marker_offset_mm"] / 1000)
    assert priors.std_of("joint_compliance.q2") == pytest.approx(values["joint_compliance_urad_per_Nm"] / 1e6)
    assert priors.std_of("joint_scale.q1") == pytest.approx(values["joint_scale_ppm"] / 1e6)
    assert priors.std_of("sensor_scale.s") == pytest.approx(values["sensor_scale_ppm"] / 1e6)
    assert priors.std_of("drift.q4", "K") == pytest.approx(math.radians(values["drift_deg_per_kelvin"]))
    assert priors.std_of("drift.q4", "s") == pytest.approx(math.radians(values["drift_deg_per_hour"]) / 3600)


def test_the_papers_parameters_keep_flat_priors():
    priors = priors_from(SECTION)
    for name in ("registration.x", "registration.gamma", "zero_offsets.q1", "zero_offsets.q7", "noise.sigma"):
        assert priors.std_of(name) == math.inf, name
        assert priors.std_of(name, "K") == math.inf, name
    with pytest.raises(ValueError, match=r"no prior for parameter 'backlash\.q1'"):
        priors.std_of("backlash.q1")


def test_report_lists_every_key_with_its_meaning():
    report = priors_from(KNOWN).report()
    assert report["arm_class"] == "industrial" and report["source"] == "config"
    assert report["std_display_units"] == KNOWN["industrial"]
    assert list(report["meaning"]) == list(KEYS)


# --------------------------------------------------------------------------- class of arm


def test_industrial_and_collaborative_differ_where_the_defaults_do():
    industrial, collaborative = priors_from(section("industrial")), priors_from(section("collaborative"))
    assert (industrial.arm_class, collaborative.arm_class) == ("industrial", "collaborative")
    differing = {k for k in KEYS if DEFAULTS["industrial"][k] != DEFAULTS["collaborative"][k]}
    assert differing == {"joint_compliance_urad_per_Nm"}
    for key in KEYS:
        assert (industrial.std(key) != collaborative.std(key)) == (key in differing), key
    # stiffer drives, smaller prior: 50 against 200 urad/(N m)
    assert industrial.std_of("joint_compliance.q2") == pytest.approx(5e-5)
    assert collaborative.std_of("joint_compliance.q2") == pytest.approx(2e-4)


def test_config_yaml_repeats_the_defaults():
    """DEFAULTS serve library calls without a config; config.yaml states the same values with reasons."""
    assert SECTION == DEFAULTS
    assert with_defaults(None) == DEFAULTS


def test_with_defaults_lays_a_partial_section_over_the_defaults():
    merged = with_defaults({"arm_class": "industrial", "industrial": {"link_translation_mm": 3.0}})
    assert merged["arm_class"] == "industrial"
    assert merged["industrial"] == {**DEFAULTS["industrial"], "link_translation_mm": 3.0}
    assert merged["collaborative"] == DEFAULTS["collaborative"]
    assert priors_from(merged).std_of("link_geometry.F3.z") == pytest.approx(3e-3)


# --------------------------------------------------------------------------- a campaign's own priors


def test_campaign_override_changes_only_its_key_and_class():
    source = "data/raw/demo/campaign.yaml"
    robot = {"urdf": "x.urdf", "priors": {"arm_class": "industrial", "link_translation_mm": 2.5}}
    priors = priors_from(section("collaborative"), robot, source)
    assert priors.arm_class == "industrial"
    assert priors.values == {**SECTION["industrial"], "link_translation_mm": 2.5}
    assert priors.std_of("link_geometry.F2.x") == pytest.approx(2.5e-3)
    assert priors.std_of("joint_compliance.q1") == pytest.approx(
        SECTION["industrial"]["joint_compliance_urad_per_Nm"] * 1e-6
    )
    assert priors.source == f"config, overridden by {source}"


def test_campaign_override_of_one_key_keeps_the_configs_class():
    priors = priors_from(section("collaborative"), {"priors": {"joint_scale_ppm": 250}}, "demo/campaign.yaml")
    assert priors.arm_class == "collaborative"
    assert priors.values == {**SECTION["collaborative"], "joint_scale_ppm": 250.0}
    assert priors.std_of("joint_scale.q5") == pytest.approx(2.5e-4)
    assert priors.source == "config, overridden by demo/campaign.yaml"


def test_no_campaign_priors_is_the_config():
    for robot in (None, {}, {"urdf": "x.urdf"}, {"priors": None}, {"priors": {}}):
        priors = priors_from(section("industrial"), robot, "demo/campaign.yaml")
        assert priors.values == SECTION["industrial"] and priors.source == "config", robot


def twin_campaign(root, priors=None, yaml_text: str | None = None):
    """data/raw/kuka-twin copied to root/kuka-twin with one sensor (its Parquet file and its entry in
    campaign.yaml), `robot.priors` set to `priors`, or written as the YAML text `yaml_text`;
    returns (folder, campaign.yaml path)."""
    folder = root / "kuka-twin"
    folder.mkdir()
    shutil.copy(TWIN / f"{SENSOR}.parquet", folder)
    meta = files.read_yaml(TWIN / "campaign.yaml")
    meta["sensors"] = {SENSOR: meta["sensors"][SENSOR]}
    if priors is not None or yaml_text is not None:
        meta["robot"]["priors"] = {"RAW": 0} if yaml_text is not None else priors
    path = files.write_yaml(folder / "campaign.yaml", meta)
    if yaml_text is not None:
        text = path.read_text()
        assert "\n  priors: {RAW: 0}\n" in text
        path.write_text(text.replace("{RAW: 0}", yaml_text))
    return folder, path


def test_a_campaign_folder_with_priors_is_read_and_overrides(tmp_path):
    folder, yaml_path = twin_campaign(tmp_path, {"arm_class": "industrial", "marker_offset_mm": 0.2})
    campaign = folders.read_campaign(folder, repo_root=REPO)
    assert campaign.robot["priors"] == {"arm_class": "industrial", "marker_offset_mm": 0.2}
    priors = priors_from(SECTION, campaign.robot, str(yaml_path))
    assert priors.arm_class == "industrial"
    assert priors.values == {**SECTION["industrial"], "marker_offset_mm": 0.2}
    assert priors.std_of("marker_offset.x") == pytest.approx(2e-4)
    assert priors.source == f"config, overridden by {yaml_path}"


# --------------------------------------------------------------------------- bad priors: campaign.yaml

BAD_CAMPAIGN_PRIORS = {
    # case: (robot/priors as written in campaign.yaml, key, message after "<file>: <key>: ")
    "unknown key": ("{link_lenght_mm: 2.0}", "robot/priors/link_lenght_mm", f"unknown prior; {ALLOWED}"),
    "negative": ("{link_translation_mm: -1.0}", "robot/priors/link_translation_mm", POSITIVE + "-1.0"),
    "zero": ("{joint_scale_ppm: 0}", "robot/priors/joint_scale_ppm", POSITIVE + "0"),
    "text": ("{marker_offset_mm: one}", "robot/priors/marker_offset_mm", POSITIVE + "'one'"),
    "no value": ("{drift_deg_per_kelvin: }", "robot/priors/drift_deg_per_kelvin", POSITIVE + "None"),
    "nan": ("{drift_deg_per_hour: .nan}", "robot/priors/drift_deg_per_hour", POSITIVE + "nan"),
    "yes": ("{sensor_scale_ppm: yes}", "robot/priors/sensor_scale_ppm", POSITIVE + "True"),
    # YAML 1.1 (PyYAML) reads 1e-3 (no point in the mantissa) as text; 1.0e-3 is a number
    "1e-3": ("{link_translation_mm: 1e-3}", "robot/priors/link_translation_mm", POSITIVE + "'1e-3'"),
    "unknown class": (
        "{arm_class: heavy, link_translation_mm: 2.0}",
        "robot/priors/arm_class",
        "must be one of industrial, collaborative, got 'heavy'",
    ),
    "not a mapping": ("[1.0, 0.1]", "robot/priors", "must be a mapping of priors, got [1.0, 0.1]"),
}


@pytest.mark.parametrize("case", BAD_CAMPAIGN_PRIORS)
def test_bad_campaign_priors_name_file_and_key(tmp_path, case):
    yaml_text, key, message = BAD_CAMPAIGN_PRIORS[case]
    folder, yaml_path = twin_campaign(tmp_path, yaml_text=yaml_text)
    with pytest.raises(InputError) as info:
        folders.read_campaign(folder, repo_root=REPO)
    assert info.value.file == str(yaml_path) and info.value.key == key
    assert str(info.value) == f"{yaml_path}: {key}: {message}"


def test_campaign_prior_written_1_0e_3_is_a_number(tmp_path):
    """The way out of the `1e-3` case above: with a point in the mantissa YAML reads a number."""
    folder, _ = twin_campaign(tmp_path, yaml_text="{link_translation_mm: 1.0e-3}")
    assert folders.read_campaign(folder, repo_root=REPO).robot["priors"] == {"link_translation_mm": 1e-3}


BAD_OVERRIDES = {
    # case: (robot.priors as a library caller gives it, key, message after "<source>: <key>: ")
    "unknown key": ({"joint_scale": 2.0}, "robot/priors/joint_scale", f"unknown prior; {ALLOWED}"),
    "zero": ({"joint_scale_ppm": 0.0}, "robot/priors/joint_scale_ppm", POSITIVE + "0.0"),
    "text": ({"link_rotation_deg": "0.1"}, "robot/priors/link_rotation_deg", POSITIVE + "'0.1'"),
    "bool": ({"sensor_scale_ppm": False}, "robot/priors/sensor_scale_ppm", POSITIVE + "False"),
    "unknown class": (
        {"arm_class": "Industrial"},
        "robot/priors/arm_class",
        "must be one of industrial, collaborative, got 'Industrial'",
    ),
    "not a mapping": (
        [("link_translation_mm", 2.0)],
        "robot/priors",
        "must be a mapping of priors, got [('link_translation_mm', 2.0)]",
    ),
}


@pytest.mark.parametrize("case", BAD_OVERRIDES)
def test_bad_campaign_priors_given_to_priors_from_directly(case):
    """The library call refuses them the same way, naming the source it is given."""
    override, key, message = BAD_OVERRIDES[case]
    with pytest.raises(InputError) as info:
        priors_from(SECTION, {"priors": override}, "kuka-twin/campaign.yaml")
    assert info.value.file == "kuka-twin/campaign.yaml" and info.value.key == key
    assert str(info.value) == f"kuka-twin/campaign.yaml: {key}: {message}"


# --------------------------------------------------------------------------- bad priors: config

BAD_CONFIG_PRIORS = {
    # case: (section, key, message after "config: <key>: ")
    "unknown key": (
        section("industrial", industrial={"link_lenght_mm": 2.0}),
        "priors/industrial/link_lenght_mm",
        f"unknown prior; {ALLOWED}",
    ),
    "negative": (
        section("collaborative", collaborative={"link_rotation_deg": -0.1}),
        "priors/collaborative/link_rotation_deg",
        POSITIVE + "-0.1",
    ),
    "zero": (
        section("industrial", industrial={"joint_compliance_urad_per_Nm": 0}),
        "priors/industrial/joint_compliance_urad_per_Nm",
        POSITIVE + "0",
    ),
    "text": (
        section("collaborative", collaborative={"drift_deg_per_kelvin": "0.02 deg"}),
        "priors/collaborative/drift_deg_per_kelvin",
        POSITIVE + "'0.02 deg'",
    ),
    "infinite": (
        section("collaborative", collaborative={"sensor_scale_ppm": math.inf}),
        "priors/collaborative/sensor_scale_ppm",
        POSITIVE + "inf",
    ),
    "unknown class": (section("heavy"), "priors/arm_class", "must be one of industrial, collaborative, got 'heavy'"),
    "class without values": (
        {"arm_class": "industrial", "collaborative": DEFAULTS["collaborative"]},
        "priors/industrial",
        "must be a mapping of priors, got None",
    ),
    "missing key": (
        {
            "arm_class": "industrial",
            "industrial": {k: v for k, v in DEFAULTS["industrial"].items() if k != "held_zero_offset_deg"},
        },
        "priors/industrial",
        "missing priors held_zero_offset_deg",
    ),
}


@pytest.mark.parametrize("case", BAD_CONFIG_PRIORS)
def test_bad_config_priors_name_the_config_and_key(case):
    config, key, message = BAD_CONFIG_PRIORS[case]
    with pytest.raises(InputError) as info:
        priors_from(config)
    assert info.value.file == "config" and info.value.key == key
    assert str(info.value) == f"config: {key}: {message}"


def test_a_campaigns_class_with_a_bad_config_value_names_the_config():
    """The campaign picks the class; the bad value is the config's, and the message says so."""
    config = section("collaborative", industrial={"link_translation_mm": -2})
    assert priors_from(config).arm_class == "collaborative"  # the class in use is fine
    with pytest.raises(InputError) as info:
        priors_from(config, {"priors": {"arm_class": "industrial"}}, "demo/campaign.yaml")
    assert str(info.value) == f"config: priors/industrial/link_translation_mm: {POSITIVE}-2"


# --------------------------------------------------------------------------- the config schema


def test_config_yaml_priors_pass_the_schema():
    config = copy.deepcopy(CONFIG)
    validate(config, SCHEMA)
    assert config["priors"] == SECTION
    assert priors_from(config["priors"]).values == SECTION[SECTION["arm_class"]]


def test_schema_default_without_a_priors_section_gives_the_defaults():
    config = copy.deepcopy(CONFIG)
    del config["priors"]
    validate(config, SCHEMA)
    assert config["priors"] == {"arm_class": "collaborative"}
    assert priors_from(with_defaults(config["priors"])).values == DEFAULTS["collaborative"]


BAD_SCHEMA_PRIORS = {
    # case: (change to config.yaml's priors section, what the schema says, where)
    "negative": (
        {"industrial": {"joint_scale_ppm": -5}},
        "-5 is less than or equal to the minimum of 0",
        "['priors']['industrial']['joint_scale_ppm']",
    ),
    "zero": (
        {"collaborative": {"link_rotation_deg": 0}},
        "0 is less than or equal to the minimum of 0",
        "['priors']['collaborative']['link_rotation_deg']",
    ),
    "text": (
        {"industrial": {"link_translation_mm": "one"}},
        "'one' is not of type 'number'",
        "['priors']['industrial']['link_translation_mm']",
    ),
    "unknown key": (
        {"industrial": {"link_lenght_mm": 1.0}},
        "Additional properties are not allowed ('link_lenght_mm' was unexpected)",
        "['priors']['industrial']",
    ),
    "unknown class": (
        {"arm_class": "heavy"},
        "'heavy' is not one of ['industrial', 'collaborative']",
        "['priors']['arm_class']",
    ),
}


@pytest.mark.parametrize("case", BAD_SCHEMA_PRIORS)
def test_bad_priors_are_refused_by_the_schema(case):
    change, says, where = BAD_SCHEMA_PRIORS[case]
    config = copy.deepcopy(CONFIG)
    for name, value in change.items():
        if isinstance(value, dict):
            config["priors"][name].update(value)
        else:
            config["priors"][name] = value
    with pytest.raises(WorkflowError) as info:
        validate(config, SCHEMA)
    message = str(info.value)
    assert message.startswith("Error validating config file.") and f"ValidationError: {says}" in message
    assert f"On instance{where}" in message


def test_schema_refuses_a_class_missing_a_key():
    config = copy.deepcopy(CONFIG)
    del config["priors"]["industrial"]["held_zero_offset_deg"]
    with pytest.raises(WorkflowError, match="'held_zero_offset_deg' is a required property"):
        validate(config, SCHEMA)


def test_schema_and_code_know_the_same_keys_and_classes():
    schema = files.read_yaml(SCHEMA)
    prior_set = schema["definitions"]["prior_set"]
    assert list(prior_set["properties"]) == list(KEYS) == prior_set["required"]
    priors = schema["properties"]["priors"]["properties"]
    assert tuple(priors["arm_class"]["enum"]) == CLASSES and priors["arm_class"]["default"] == DEFAULTS["arm_class"]


# --------------------------------------------------------------------------- how the arm reads its joints


def test_encoders_at_the_output_give_the_joint_scale_its_prior_of_tens_of_ppm():
    """robot/joint_encoders: output takes joint_scale_output_ppm (30 ppm in config.yaml) for every
    joint's scale, motor (and no key: unknown) joint_scale_ppm; nothing else changes."""
    assert JOINT_ENCODERS == ("motor", "output")
    output = priors_from(section("collaborative"), {"joint_encoders": "output"}, "ur5/campaign.yaml")
    motor = priors_from(section("collaborative"), {"joint_encoders": "motor"}, "ur5/campaign.yaml")
    unknown = priors_from(section("collaborative"), {}, "ur5/campaign.yaml")
    assert output.std_of("joint_scale.q2") == pytest.approx(SECTION["collaborative"]["joint_scale_output_ppm"] * 1e-6)
    assert output.std_of("joint_scale.q2") == pytest.approx(30e-6)
    assert motor.std_of("joint_scale.q2") == unknown.std_of("joint_scale.q2") == pytest.approx(1e-3)
    assert output.std_of("link_geometry.F2.x") == motor.std_of("link_geometry.F2.x")
    assert output.report()["joint_encoders"] == "output" and unknown.joint_encoders == "motor"


BAD_ENCODERS = {
    # case: (robot/joint_encoders as written in campaign.yaml, what the message quotes)
    "unknown": ("gearbox", "'gearbox'"),
    "capitals": ("Output", "'Output'"),
    "a list": ("[motor, output]", "['motor', 'output']"),
    "empty": ("''", "''"),
}


@pytest.mark.parametrize("case", BAD_ENCODERS)
def test_bad_joint_encoders_name_file_and_key(tmp_path, case):
    """campaign.yaml's robot/joint_encoders not motor or output: refused when the folder is read,
    naming the file, the key and the choices."""
    written, quoted = BAD_ENCODERS[case]
    folder, yaml_path = twin_campaign(tmp_path)
    meta = files.read_yaml(yaml_path)
    meta["robot"]["joint_encoders"] = "RAW"
    files.write_yaml(yaml_path, meta)
    yaml_path.write_text(yaml_path.read_text().replace("RAW", written, 1))
    with pytest.raises(InputError) as info:
        folders.read_campaign(folder, repo_root=REPO)
    assert info.value.file == str(yaml_path) and info.value.key == "robot/joint_encoders"
    assert str(info.value) == (
        f"{yaml_path}: robot/joint_encoders: must be one of motor, output (where the encoders read the joint: "
        f"on the motor, before the gear, or at the joint's output), got {quoted}"
    )


def test_a_campaign_folder_with_output_encoders_is_read(tmp_path):
    folder, yaml_path = twin_campaign(tmp_path)
    meta = files.read_yaml(yaml_path)
    meta["robot"]["joint_encoders"] = "output"
    files.write_yaml(yaml_path, meta)
    campaign = folders.read_campaign(folder, repo_root=REPO)
    assert campaign.robot["joint_encoders"] == "output"
    assert priors_from(SECTION, campaign.robot, str(yaml_path)).std_of("joint_scale.q1") == pytest.approx(30e-6)
