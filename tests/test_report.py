"""The HTML report is one self-contained page with every table and figure it is given."""

import base64

import pandas as pd

from remaster.reporting import report

PNG = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg==")


def _summary(name="c1", date="2020-01-01"):
    return {"campaign": name, "date": date,
            "robot": {"name": "arm", "joints": ["j1", "j2"], "base": "b", "flange": "f"},
            "sensors": {"laser_tracker": {"kind": "laser_tracker", "n_missing": 2, "missing_rows": [4, 9],
                                          "sets": {"optimization": {"poses": 3, "configurations": 7}}}}}


def test_page_embeds_tables_and_figures():
    summary = _summary()
    table = pd.DataFrame({"Parameter": ["x (mm)", "<b>"], "MLE": [1.23456, float("nan")]})
    page = report.build({"c1": {"summary": summary, "tables": {"registration_params": table},
                                "figures": {"zero_offset_trace_laser_tracker": PNG}}},
                        {"registration_params": "Registration", "zero_offset_trace": "Trace"})
    assert page.startswith("<!DOCTYPE html>") and "</html>" in page
    assert "<caption>Registration</caption>" in page and "1.235" in page
    assert "&lt;b&gt;" in page  # text is escaped, never injected
    assert "data:image/png;base64," + base64.b64encode(PNG).decode() in page
    assert "Trace (laser tracker)" in page
    assert "2 rows without a measurement" in page and "[4, 9]" in page
    assert "src=\"http" not in page and "href=\"http" not in page  # nothing fetched from outside


def test_campaigns_are_shown_in_date_order():
    names = {"b-first": "2018-03-01", "a-last": "2021-06-30", "c-middle": "2019-11-05", "a-middle": "2019-11-05"}
    page = report.build({n: {"summary": _summary(n, d), "tables": {}, "figures": {}} for n, d in names.items()}, {})
    headings = [page.index(f"<h2 id='{n}'>") for n in ("b-first", "a-middle", "c-middle", "a-last")]
    assert headings == sorted(headings)


def test_a_file_column_is_a_column_of_links_beside_the_page():
    table = pd.DataFrame({"Sensor": ["laser_tracker"], "File": ["demo/laser_tracker/calibrated/loop.urdf"],
                          "What": ["a <calibrated> URDF"]})
    page = report.table_html("files", table)
    assert '<a href="demo/laser_tracker/calibrated/loop.urdf">demo/laser_tracker/calibrated/loop.urdf</a>' in page
    assert "a &lt;calibrated&gt; URDF" in page and page.count("<a href") == 1  # only the File column links
