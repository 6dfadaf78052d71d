"""`dynid report`: the page against `dynid validate/detect --json`, the model file and truth.json, rendered in a
real headless browser; and its bad input."""

from __future__ import annotations

import base64
import hashlib
import json
import math
import re
import shutil
import struct
import subprocess
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import dynid

from dynid.report.figures import envelope
from dynid.report.page import representative_window

FIGURES = ("fig-t2-validation", "fig-t2-contact", "fig-roc", "fig-traces")


class Page(HTMLParser):
    """The parts of the report page the tests look at."""

    def __init__(self) -> None:
        super().__init__()
        self.images: list[dict[str, str]] = []
        self.figures: list[str] = []
        self.cells: list[dict[str, str]] = []  # elements with data-key, with their text
        self.tables = 0
        self.scripts = 0
        self._open: list[dict[str, str]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        if tag == "img":
            self.images.append(a)
        elif tag == "figure":
            self.figures.append(a.get("id", ""))
        elif tag == "table":
            self.tables += 1
        elif tag == "script":
            self.scripts += 1
        if "data-key" in a:
            a["text"] = ""
            self.cells.append(a)
            self._open.append(a)

    def handle_data(self, data: str) -> None:
        for a in self._open:
            a["text"] += data

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "span") and self._open:
            self._open.pop()


def parse(path: Path) -> Page:
    p = Page()
    p.feed(path.read_text(encoding="utf-8"))
    return p


def at(result: Any, key: str) -> Any:
    for part in key.split("/"):
        result = result[int(part)] if isinstance(result, list) else result[part]
    return result


def load(path: Path) -> dict:
    return json.loads(path.read_text())


@pytest.fixture(scope="module")
def report(default_experiments: dict[str, Path], default_model: Path, tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("report")
    v, c = str(default_experiments["validation"]), str(default_experiments["contact"])
    runs = {
        "report": ("report", "--model", str(default_model), "--validation", v, "--contact", c, "--out", str(d / "r.html")),
        "validate": ("validate", "--model", str(default_model), "--data", v),
        # the page shows detect's default variants: the combined detector, the momentum observer and the paper's two
        # acceleration-based detectors (its Fig. 3-5)
        "detect_contact": ("detect", "--model", str(default_model), "--data", c),
        "detect_validation": ("detect", "--model", str(default_model), "--data", v),
    }
    out = {"html": d / "r.html", "dir": d}
    for name, args in runs.items():
        out[name] = d / f"{name}.json"
        done = dynid(*args, "--json", str(out[name]))
        assert done.returncode == 0, done.stderr
        if name == "report":
            out["stdout"] = done.stdout
    return out


def test_numbers_are_those_of_validate_and_detect(report) -> None:
    r = load(report["report"])
    assert r["validation"] == load(report["validate"])
    # detect's `out_of_sample` (whether DATA lies outside the fit, and the in-sample calibration's FPR beside), its
    # events, its monitor-style events and what it calibrated on are the command's own report on its input, not figures of the page
    for run in ("contact", "validation"):
        detected = load(report[f"detect_{run}"])
        for own in ("out_of_sample", "events", "monitor_events", "calibration"):
            assert own in detected
            detected.pop(own)
        assert r["detection"][run] == detected and list(detected["variants"]) == ["combined", "momentum", "calibrated",
                                                                                  "paper"]
    # the printed summary quotes the same numbers
    calibrated = r["detection"]["contact"]["variants"]["calibrated"]
    assert f"TPR {100 * calibrated['tpr']:.1f} %" in report["stdout"]
    assert f"{r['validation']['table_ii']['identified']['force']['mean']:.3f} N identified" in report["stdout"]


def shown_tolerance(text: str) -> float:
    """Half a unit of the last digit shown: '0.107' -> 5e-4, '4.5e-05' -> 5e-7."""
    mantissa, _, exponent = text.strip().lstrip("+-").partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (int(exponent or 0) - decimals)


def test_page_numbers_match_the_json(report) -> None:
    r, page = load(report["report"]), parse(report["html"])
    keyed = [c for c in page.cells if c.get("data-value")]
    assert len(keyed) > 300  # every table: Table II, channels, detection, gains, 87 base parameters × 5
    for c in keyed:
        value = at(r, c["data-key"])
        assert float(c["data-value"]) == value, c["data-key"]
        shown = value * float(c.get("data-scale", 1.0))
        assert abs(float(c["text"]) - shown) <= shown_tolerance(c["text"]) * (1 + 1e-9), (c["data-key"], c["text"])
    keys = {c["data-key"] for c in keyed}
    for must in ("validation/table_ii/identified/force/mean", "validation/table_ii/cad/force/mean",
                 "validation/channels/pwm.m0/rms", "detection/contact/variants/calibrated/tpr",
                 "detection/contact/variants/paper/fpr", "detection/validation/variants/calibrated/fpr",
                 "detection/contact/variants/calibrated/auc", "detection/contact/variants/calibrated/tpr_by_side/distal",
                 "paper/tpr", "paper/force_error/0", "parameters/86/true", "truth_check/rms_error_in_se",
                 "validation/relative_error/overall", "validation/relative_error/channels/pwm.m3/relative"):
        assert must in keys, must


def png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_page_holds_every_figure_and_stands_alone(report) -> None:
    page = parse(report["html"])
    assert page.figures == list(FIGURES)
    assert len(page.images) == len(FIGURES)
    for img in page.images:
        assert img["src"].startswith("data:image/png;base64,")
        w, h = png_size(base64.b64decode(img["src"].split(",", 1)[1]))
        assert w > 300 and h > 150
    text = report["html"].read_text(encoding="utf-8")
    assert page.scripts == 0 and not re.search(r"(src|href)=\"(?!data:)", text)  # nothing to fetch
    assert page.tables >= 5


def test_parameter_table_against_model_and_truth(report, default_model: Path, default_experiments) -> None:
    r, model = load(report["report"]), load(default_model)
    truth = load(default_experiments["identification"] / "truth.json")
    base, rows = model["base"], r["parameters"]
    assert r["truth"] == str((default_experiments["identification"] / "truth.json").resolve())
    assert [x["combination"] for x in rows] == base["combinations"]
    assert [x["identified"] for x in rows] == base["values"]
    assert [x["standard_error"] for x in rows] == base["standard_errors"]
    assert [x["determined"] for x in rows] == base["identified"]

    # Our own reading of each combination 'a + k·b - k·c' (regex, not the report's parser).
    def terms(text: str) -> list[tuple[float, str]]:
        head, rest = text.split(" ", 1) if " " in text else (text, "")
        return [(1.0, head)] + [(float(k) * (-1 if s == "-" else 1), n)
                                for s, k, n in re.findall(r"([+-]) ([0-9.e+-]+)·(\S+)", rest)]

    phi_model, phi_true = model["parameters"], truth["parameters"]
    for row in rows:
        t = terms(row["combination"])
        # the combination applied to the model's own Φ gives back its base value (K read back from the text)
        scale = sum(abs(k * phi_model[n]) for k, n in t) + 1e-12
        assert abs(sum(k * phi_model[n] for k, n in t) - row["identified"]) <= 2e-5 * scale, row["name"]
        true = sum(k * phi_true[n] for k, n in t)
        assert row["true"] == pytest.approx(true, rel=1e-12, abs=1e-15)
        assert row["error_in_se"] == pytest.approx((row["identified"] - true) / row["standard_error"])
        # the CAD combination differs from the identified one only in the leading parameter (the model's Φ_d is
        # the CAD's), up to the six digits K is written with
        cad_lead = truth["cad_parameters"].get(row["name"])
        if row["cad"] is not None and cad_lead is not None and not row["name"].startswith("ft."):
            assert abs(row["cad"] - (row["identified"] - phi_model[row["name"]] + cad_lead)) <= 2e-5 * scale, row["name"]
    gains = {g["name"]: g for g in r["motor_gains"]}
    assert set(gains) == {n for n in phi_true if n.endswith(".phi_m")}
    for name, g in gains.items():
        assert g["true"] == phi_true[name]
        assert set(g["estimators"]) == set(model["estimators"])
    cad_defined = [x for x in rows if x["cad"] is not None]
    assert all(not x["name"].endswith(".phi_m") for x in cad_defined)  # a CAD model has no gains
    assert len(cad_defined) > 10


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
OFFLINE = ["--headless", "--no-sandbox", "--disable-gpu", "--no-proxy-server", "--host-resolver-rules=MAP * ~NOTFOUND",
           "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
           "--disable-dev-shm-usage", "--hide-scrollbars"]


def chromium(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, *OFFLINE, f"--user-data-dir={tmp / 'profile'}", *args],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium (scripts/setup installs Debian's chromium as root)")
def test_renders_in_headless_chromium(report, tmp_path: Path) -> None:
    # A copy of the page with a probe that records, once loaded, each image's decoded width.
    probe = tmp_path / "probe.html"
    probe.write_text(report["html"].read_text(encoding="utf-8").replace("</body>", (
        "<script>window.addEventListener('load', function () { document.body.setAttribute('data-widths', "
        "Array.from(document.images).map(function (i) { return i.complete ? i.naturalWidth : -1; }).join(' ')); "
        "});</script></body>")), encoding="utf-8")
    done = chromium(tmp_path, "--virtual-time-budget=10000", "--dump-dom", probe.as_uri())
    assert done.returncode == 0, done.stderr[-2000:]
    found = re.search(r'data-widths="([^"]*)"', done.stdout)
    assert found, "the page did not finish loading in chromium"
    widths = [int(w) for w in found.group(1).split()]
    assert len(widths) == len(FIGURES) and all(w > 300 for w in widths), widths

    # And the page as painted: a screenshot of the top (tables and the first figure) is not blank.
    shot = tmp_path / "shot.png"
    done = chromium(tmp_path, "--window-size=1200,2400", f"--screenshot={shot}", report["html"].as_uri())
    assert done.returncode == 0 and shot.is_file(), done.stderr[-2000:]
    from PIL import Image

    pixels = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    assert pixels.shape[:2] == (2400, 1200)
    assert pixels.std() > 20 and len(np.unique(pixels.reshape(-1, 3), axis=0)) > 200


def test_without_truth(default_experiments, default_model, tmp_path: Path) -> None:
    """Real data have no truth.json: the page leaves the true column out rather than inventing one."""
    m = load(default_model)
    for d in m["data"]:
        d["path"] = str(tmp_path / "elsewhere")  # the identification run's directory (and its truth) is gone
    (tmp_path / "model.json").write_text(json.dumps(m))
    for kind in ("validation", "contact"):
        shutil.copy(default_experiments[kind] / "dataset.npz", tmp_path / f"{kind}.npz")
    done = dynid("report", "--model", str(tmp_path / "model.json"), "--validation", str(tmp_path / "validation.npz"),
                 "--contact", str(tmp_path / "contact.npz"), "--out", str(tmp_path / "r.html"),
                 "--json", str(tmp_path / "r.json"))
    assert done.returncode == 0, done.stderr
    r, page = load(tmp_path / "r.json"), parse(tmp_path / "r.html")
    assert r["truth"] is None and r["truth_check"] is None
    assert all(x["true"] is None and x["error_in_se"] is None for x in r["parameters"])
    assert all(g["true"] is None for g in r["motor_gains"])
    assert not any(c["data-key"].endswith("/true") for c in page.cells)
    assert page.figures == list(FIGURES) and "No true parameters known" in (tmp_path / "r.html").read_text()


# ------------------------------------------------------------------------------------------------------------
# Bad input: exit 2 and one line


def one_line_exit_2(done: subprocess.CompletedProcess, *words: str) -> None:
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    for w in words:
        assert w in lines[0], lines[0]


def run_report(model: Path | str, validation: Path | str, contact: Path | str, out: Path) -> subprocess.CompletedProcess:
    return dynid("report", "--model", str(model), "--validation", str(validation), "--contact", str(contact),
                 "--out", str(out))


def test_a_validation_run_with_contacts_is_noted(default_experiments, default_model, tmp_path: Path) -> None:
    # As `dynid validate` notes it: the errors and the false positives then count the contacts the model lacks.
    c = default_experiments["contact"]
    done = run_report(default_model, c, c, tmp_path / "r.html")
    assert done.returncode == 0, done.stderr
    assert dynid("validate", "--model", str(default_model), "--data", str(c), "--json", str(tmp_path / "v.json")
                 ).returncode == 0
    fraction = json.loads((tmp_path / "v.json").read_text())
    page = (tmp_path / "r.html").read_text()
    share = f"{100 * fraction['contact_fraction']:.1f} % of the validation run's samples are in contact"
    assert share in page and "false positives below count its contacts as false" in page


def test_missing_files(default_experiments, default_model, tmp_path: Path) -> None:
    v, c, out = default_experiments["validation"], default_experiments["contact"], tmp_path / "r.html"
    one_line_exit_2(run_report(tmp_path / "none.json", v, c, out), "model file not found")
    one_line_exit_2(run_report(default_model, tmp_path / "none", c, out), "not found", "none")
    one_line_exit_2(run_report(default_model, v, tmp_path / "gone.csv", out), "not found", "gone.csv")
    one_line_exit_2(run_report(default_model, v, c, tmp_path / "no" / "r.html"), "does not exist")
    assert not out.exists()


def test_model_of_another_robot(default_experiments, default_model, tmp_path: Path) -> None:
    """A model file fitted for another arm (same joints, another name) is refused against this arm's data."""
    m = load(default_model)
    text = m["robot"]["config_text"].replace("name: icub_right_arm", "name: other_arm", 1)
    assert text != m["robot"]["config_text"]
    m["robot"] = {"name": "other_arm", "config_digest": hashlib.sha256(text.encode()).hexdigest(),
                  "config_source": str(tmp_path / "gone" / "other_arm.yaml"), "config_text": text}
    other = tmp_path / "other.json"
    other.write_text(json.dumps(m))
    done = run_report(other, default_experiments["validation"], default_experiments["contact"], tmp_path / "r.html")
    one_line_exit_2(done, "icub_right_arm", "other_arm")


def test_contact_data_without_contact_column(default_experiments, default_model, tmp_path: Path) -> None:
    v = default_experiments["validation"]
    done = run_report(default_model, v, v, tmp_path / "r.html")
    one_line_exit_2(done, "no 'contact' column")
    assert not (tmp_path / "r.html").exists()


def test_foreign_truth_file(default_experiments, default_model, tmp_path: Path) -> None:
    truth = load(default_experiments["identification"] / "truth.json")
    truth["robot"] = "other_arm"
    (tmp_path / "truth.json").write_text(json.dumps(truth))
    done = dynid("report", "--model", str(default_model), "--validation", str(default_experiments["validation"]),
                 "--contact", str(default_experiments["contact"]), "--out", str(tmp_path / "r.html"),
                 "--truth", str(tmp_path / "truth.json"))
    one_line_exit_2(done, "other_arm")


def test_another_arms_truth_of_the_same_robot_is_refused(default_experiments, default_model, tmp_path: Path) -> None:
    # Another `dynid simulate --robot-seed`: the same robot's name, other true parameters than the fitted data's.
    truth = load(default_experiments["identification"] / "truth.json")
    truth["robot_seed"] += 1
    truth["parameters"] = {k: 1.01 * v for k, v in truth["parameters"].items()}
    (tmp_path / "truth.json").write_text(json.dumps(truth))
    done = dynid("report", "--model", str(default_model), "--validation", str(default_experiments["validation"]),
                 "--contact", str(default_experiments["contact"]), "--out", str(tmp_path / "r.html"),
                 "--truth", str(tmp_path / "truth.json"))
    one_line_exit_2(done, "holds another icub_right_arm's truth than the model was fitted on")
    assert not (tmp_path / "r.html").exists()


# ------------------------------------------------------------------------------------------------------------
# Helpers, on synthetic signals


def test_envelope_keeps_every_peak() -> None:
    rng = np.random.default_rng(1)
    y = rng.standard_normal(100_003)
    y[54_321] = 50.0
    t = np.arange(y.size) * 1e-3
    tt, lo, hi = envelope(t, y, bins=500)
    assert tt.size == lo.size == hi.size == 500
    assert hi.max() == 50.0 and lo.min() == y.min()
    assert np.all(lo <= hi)


def test_representative_window_is_the_median_one() -> None:
    t = np.arange(10_000) * 1e-3  # 10 s, windows of 1 s
    scale = np.repeat([5.0, 1.0, 9.0, 3.0, 7.0, 2.0, 8.0, 4.0, 6.0, 10.0], 1000)
    e = np.column_stack([scale, 2 * scale])
    w = representative_window(t, e, np.array([1.0, 2.0]), 1.0)
    assert math.isclose(scale[w].mean(), 5.0) and w.stop - w.start == 1000


def test_windows_and_episodes_as_every_command_takes_them(default_experiments, default_model, tmp_path: Path) -> None:
    """RUN@FROM:TO and --from/--to cut the runs as `dynid validate` and `detect` cut them; --episodes labels the
    contact run as `dynid detect --episodes` does (here the run's own contact column, written as labels: the same
    rates)."""
    from dynid.io.dataset import Dataset, contact_episodes

    v, c = default_experiments["validation"], default_experiments["contact"]
    ds = Dataset.load(c / "dataset.npz")
    labels = tmp_path / "labels.csv"
    labels.write_text("t_start,t_end\n" + "".join(f"{float(ds.t[a])!r},{float(ds.t[b - 1])!r}\n"
                                                  for a, b in contact_episodes(ds.contact)))
    t0 = float(ds.t[0])
    window = f"@{t0 + 2.0!r}:{t0 + 18.0!r}"
    out = tmp_path / "r.json"
    done = dynid("report", "--model", str(default_model), "--validation", f"{v}@5:25", "--contact", f"{c}{window}",
                 "--episodes", str(labels), "--out", str(tmp_path / "r.html"), "--json", str(out))
    assert done.returncode == 0, done.stderr
    validated = dynid("validate", "--model", str(default_model), "--data", f"{v}@5:25", "--json", "-")
    detected = dynid("detect", "--model", str(default_model), "--data", f"{c}{window}", "--residual", "acceleration",
                     "--json", "-")
    r = load(out)
    table, expected_table = r["validation"]["table_ii"], json.loads(validated.stdout)["table_ii"]
    for model in ("identified", "cad"):
        for what in ("force", "torque"):
            assert table[model][what]["mean"] == pytest.approx(expected_table[model][what]["mean"], rel=1e-9)
    rates, expected = r["detection"]["contact"]["variants"], json.loads(detected.stdout)["variants"]
    for variant in ("calibrated", "paper"):
        assert rates[variant]["tpr"] == pytest.approx(expected[variant]["tpr"], rel=1e-9)
        assert rates[variant]["fpr"] == pytest.approx(expected[variant]["fpr"], rel=1e-9)
    one_line_exit_2(dynid("report", "--model", str(default_model), "--validation", str(v), "--episodes", str(labels),
                          "--out", str(tmp_path / "x.html")), "--episodes labels the contact run")


def test_the_rocs_chance_line_is_the_diagonal_on_the_log_axis_too() -> None:
    """It was drawn as one straight segment from (1e-5, 1e-5) to (1, 1): on the log-FPR panel a curve bending up to
    the right, under which a good ROC (AUC 0.83, a walkthrough) seemed to lie below chance."""
    from dynid.report.figures import roc_figure

    curve = {"fpr": [0.0, 0.001, 0.01, 0.1, 1.0], "tpr": [0.0, 0.5, 0.7, 0.9, 1.0]}
    fig = roc_figure({"calibrated": curve}, {"calibrated": (0.01, 0.7)}, {"calibrated": 0.9}, 0.99)
    for ax in fig.axes:
        (chance,) = [line for line in ax.lines if line.get_gid() == "chance"]
        x, y = chance.get_xdata(), chance.get_ydata()
        assert len(x) > 50 and np.allclose(x, y)  # TPR = FPR at every drawn point, dense enough on a log axis


def test_a_validation_run_that_is_the_fits_own_is_said_in_sample(default_experiments, default_model,
                                                                  tmp_path: Path) -> None:
    """`report --validation` on the fit's own run: `validate` says its figures are in-sample, the report said nothing
    (a walkthrough: 73 % of TIAGo's validation samples were the fit's). Now both the page and the command say so."""
    run = default_experiments["identification"]
    done = dynid("report", "--model", str(default_model), "--validation", f"{run}@10:30", "--out", str(tmp_path / "r.html"),
                 "--json", str(tmp_path / "r.json"))
    assert done.returncode == 0, done.stderr
    assert load(tmp_path / "r.json")["validation"]["fit_overlap"] == 1.0
    assert "note: 100 % of the validation run's samples are the fit's own: its figures are in-sample" in done.stdout
    assert "100 % of the validation run's samples are the fit's own (its run, inside its window): the figures below " \
           "are in-sample" in (tmp_path / "r.html").read_text()
