"""The HTML report is one self-contained page with every table and figure it is given."""

import base64
import html
import re
import urllib.parse

import pandas as pd
import pytest

from remaster.reporting import report

PNG = base64.b64decode(
    "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=="
)


def _summary(name="c1", date="2020-01-01"):
    return {
        "campaign": name,
        "date": date,
        "robot": {"name": "arm", "joints": ["j1", "j2"], "base": "b", "flange": "f"},
        "sensors": {
            "laser_tracker": {
                "kind": "laser_tracker",
                "n_missing": 2,
                "missing_rows": [4, 9],
                "sets": {"optimization": {"poses": 3, "configurations": 7}},
            }
        },
    }


def test_page_embeds_tables_and_figures():
    summary = _summary()
    table = pd.DataFrame({"Parameter": ["x (mm)", "<b>"], "MLE": [1.23456, float("nan")]})
    page = report.build(
        {
            "c1": {
                "summary": summary,
                "tables": {"registration_params": table},
                "figures": {"zero_offset_trace_laser_tracker": PNG},
            }
        },
        {"registration_params": "Registration", "zero_offset_trace": "Trace"},
    )
    assert page.startswith("<!DOCTYPE html>") and "</html>" in page
    assert (
        "<caption>Registration</caption>" in page and "<td>1.23</td>" in page
    )  # three significant digits: no std beside it
    assert "&lt;b&gt;" in page  # text is escaped, never injected
    assert "data:image/png;base64," + base64.b64encode(PNG).decode() in page
    assert "Trace (laser tracker)" in page
    assert "2 rows without a measurement" in page and "[4, 9]" in page
    assert 'src="http' not in page and 'href="http' not in page  # nothing fetched from outside


def test_campaigns_are_shown_in_date_order():
    names = {"b-first": "2018-03-01", "a-last": "2021-06-30", "c-middle": "2019-11-05", "a-middle": "2019-11-05"}
    page = report.build({n: {"summary": _summary(n, d), "tables": {}, "figures": {}} for n, d in names.items()}, {})
    headings = [page.index(f"<h2 id='{n}'>") for n in ("b-first", "a-middle", "c-middle", "a-last")]
    assert headings == sorted(headings)


def test_a_file_column_is_a_column_of_links_beside_the_page():
    table = pd.DataFrame(
        {
            "Sensor": ["laser_tracker"],
            "File": ["demo/laser_tracker/calibrated/loop.urdf"],
            "What": ["a <calibrated> URDF"],
        }
    )
    page = report.table_html("files", table)
    assert '<a href="./demo/laser_tracker/calibrated/loop.urdf">demo/laser_tracker/calibrated/loop.urdf</a>' in page
    assert "a &lt;calibrated&gt; URDF" in page and page.count("<a href") == 1  # only the File column links


@pytest.mark.parametrize(
    "folder",
    ["javascript:alert(1)", "JavaScript:alert(1)", " javascript:alert(1)", "//evil.example", "data:text/html,x"],
)
def test_no_campaign_folder_name_makes_a_link_leave_the_results(folder):
    """A campaign folder's name becomes the start of a File link: it can never give it a scheme or a host."""
    page = report.table_html("files", pd.DataFrame({"File": [f"{folder}/laser_tracker/calibrated/loop.urdf"]}))
    href = html.unescape(re.search(r'<a href="([^"]*)">', page).group(1))
    assert urllib.parse.urlsplit(href).scheme == "" and ":" not in href and " " not in href
    assert urllib.parse.urljoin("https://lab.example/results/report.html", href).startswith(
        "https://lab.example/results/"
    )
    assert f">{html.escape(folder)}/laser_tracker/calibrated/loop.urdf</a>" in page


def test_numbers_are_rounded_to_their_uncertainty_in_every_text_form(tmp_path):
    """Two significant digits of a std, its value (and the quantiles beside it) to the same
    decimal; counts as integers; numbers written as text (a column mixing numbers and 'held', as
    read back from CSV) rounded the same way; the CSV keeps every digit."""
    import math

    from remaster import files
    from remaster.reporting import tables

    table = pd.DataFrame(
        {
            "Joint": ["j1", "j2", "j3"],
            "Correction (deg)": [0.0, -0.18938243654688053, 12.3456],
            "Std (deg)": [float("nan"), 0.008883956444893744, 1.04],
            "2.5% (deg)": [float("nan"), -0.2068123, 10.2791],
            "Laser Tracker MLE (deg)": ["held", "-0.1920376699042468", "0.5"],
            "Laser Tracker Std (deg)": ["held", "0.008960076849942784", "0.25"],
            "points": [173.0, 12.0, 3.0],
            "z": [3.21234, -0.000123456, 1234.5678],
        }
    )
    cells = tables.formatted(table)
    assert cells[0] == ["j1", "0", "", "", "held", "held", "173", "3.21"]
    assert cells[1] == ["j2", "-0.1894", "0.0089", "-0.2068", "-0.1920", "0.0090", "12", "-0.000123"]
    assert cells[2] == ["j3", "12.3", "1.0", "10.3", "0.50", "0.25", "3", "1235"]
    # a std that rounds up to the next power of ten keeps two significant digits as shown
    edge = tables.formatted(pd.DataFrame({"mean (mm)": [1.8772, 12.34], "U(mean) (mm)": [0.0998, 9.96]}))
    assert edge == [["1.88", "0.10"], ["12", "10"]]
    # every text form says the same
    tables.write_table(tmp_path / "t", table, "caption", "t")
    markdown = (tmp_path / "t.md").read_text()
    assert "| j2 | -0.1894 | 0.0089 | -0.2068 | -0.1920 | 0.0090 | 12 | -0.000123 |" in markdown
    assert r"j2 & -0.1894 & 0.0089 & -0.2068 & -0.1920 & 0.0090 & 12 & -0.000123 \\" in (tmp_path / "t.tex").read_text()
    assert "<td>-0.1894</td><td>0.0089</td>" in report.table_html("t", table)
    back = files.read_csv(tmp_path / "t.csv")
    assert back.loc[1, "Correction (deg)"] == -0.18938243654688053 and back.loc[2, "z"] == 1234.5678
    assert math.isnan(back.loc[0, "Std (deg)"])


def test_a_number_without_uncertainty_shows_three_significant_digits():
    from remaster.units import shown

    assert [shown(v) for v in (6.3138, 0.0102345, -1234.56, 173.0, 0.0, 2.5)] == [
        "6.31",
        "0.0102",
        "-1235",
        "173",
        "0",
        "2.50",
    ]
    assert shown(float("nan")) == "nan"
    # tiny numbers in scientific form, three significant digits; from 1e-4 up as before
    assert [shown(v) for v in (-6.5912e-7, 2.3e-6, 9.99e-5, 1e-4, 0.000123456, -1e-12)] == [
        "-6.59e-07",
        "2.30e-06",
        "9.99e-05",
        "0.000100",
        "0.000123",
        "-1.00e-12",
    ]


def test_tiny_numbers_in_tables_print_in_scientific_form():
    from remaster.reporting import tables
    from remaster.units import shown_to

    # rounded to the decimal of an uncertainty: the same last digit, scientific when tiny
    assert [
        shown_to(v, d)
        for v, d in ((-6.5912e-7, 9), (2.34e-8, 9), (-0.18938, 4), (0.00004, 4), (1e-12, 9), (0.00012, 6), (4.4e-5, 6))
    ] == ["-6.59e-07", "2.3e-08", "-0.1894", "0.0000", "0.000000000", "0.000120", "4.4e-05"]
    table = pd.DataFrame(
        {
            "Candidate": ["drift", "gravity"],
            "gain (nats)": [-6.5912e-7, 2.3012e-6],
            "mean (mm)": [6.5912e-7, 0.123],
            "U(mean) (mm)": [2.34e-8, 0.0123],
            "value": [12.3, 0.0102],
        }
    )
    assert tables.formatted(table) == [
        ["drift", "-6.59e-07", "6.59e-07", "2.3e-08", "12.3"],
        ["gravity", "2.30e-06", "0.123", "0.012", "0.0102"],
    ]
    assert "| drift | -6.59e-07 | 6.59e-07 | 2.3e-08 | 12.3 |" in tables.to_markdown(table)
    assert tables.formatted(pd.DataFrame({"x": ["-6.5912e-07"]})) == [["-6.59e-07"]]  # a number read back as text


def test_a_failed_campaign_is_a_red_row_with_its_message_and_none_of_its_numbers():
    """A run in which one campaign failed: the report is of the others; the failed one is a red row
    of the overview with what failed, the message escaped, and no section of its own."""
    table = pd.DataFrame({"Campaign": ["good"], "Verdict": ["accepted"]})
    message = "logs/bad/laser_tracker/prepare.log: LinAlgError: <script>alert(1)</script> & not positive definite"
    page = report.build(
        {"good": {"summary": _summary("good"), "tables": {"certificate_verdict": table}, "figures": {}}},
        {},
        failed={"bad": message},
    )
    rows = re.findall(r"<tr class='failed'>(.*?)</tr>", page, flags=re.S)
    assert rows == [f"<td>bad</td><td>{html.escape(message)}</td>"]
    assert "<script>" not in page and "&lt;script&gt;alert(1)&lt;/script&gt; &amp; not positive definite" in page
    assert "tr.failed td { background: #fde8e8; color: #a00000;" in page
    assert "This run failed for 1 of its 2 campaigns (bad)" in page
    assert "<h2 id='good'>good</h2>" in page and "<h2 id='bad'>" not in page
    assert page.index(report.FAILED_CAPTION) < page.index("The run at a glance")
    # no campaign failed: no such table
    page = report.build({"good": {"summary": _summary("good"), "tables": {}, "figures": {}}}, {})
    assert report.FAILED_CAPTION not in page and "class='failed'" not in page
