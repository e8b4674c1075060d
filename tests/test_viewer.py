"""The 3-D viewer in the browser (flexparcel.viz.viewer, ``flexparcel view``).

A tiny results folder: the small example consignment (20 mm shells, a rigid rounded box),
not assembled, dropped for a few milliseconds through the drop scenario's ``write`` with the
viewer as its picture writer (seconds). The page is checked as text (frames, fields, nothing
fetched) and, where Chromium is installed (``make browser-test`` installs it), rendered
headless: the scene must be drawn (WebGL canvas, a non-blank screenshot) and the page must
expose its frame count.
"""

from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from raw_snapshots import SMALL, raw_snapshot

ROOT = Path(__file__).resolve().parents[1]
T_END = 0.004


@pytest.fixture(scope="module")
def drop_dir(tmp_path_factory):
    from flexparcel.consignments.userfile import load_consignment_file
    from flexparcel.scenarios.registry import get_scenario
    from flexparcel.viz.scenario_pictures import with_viewer

    scenario = get_scenario("drop-horizontal")
    snap = raw_snapshot(load_consignment_file(SMALL))
    result = scenario.run(snap, t_end=T_END)
    out = tmp_path_factory.mktemp("viewer") / "drop"
    files = scenario.write(result, out, pictures=with_viewer(None))
    return out, files


def _page_data(text: str) -> dict:
    m = re.search(r'<script type="application/json" id="flexparcel-data">(.*?)</script>', text,
                  re.DOTALL)  # fmt: skip
    assert m, "no data block in the page"
    return json.loads(m.group(1))


def test_write_leaves_the_viewer_next_to_the_results(drop_dir):
    out, files = drop_dir
    assert files["viewer"] == out / "view.html" and files["viewer"].is_file()
    listed = json.loads((out / "responses.json").read_text())["files"]
    assert listed["viewer"] == str(out / "view.html")
    assert not list(out.glob(".view.html.*"))  # written atomically: no temporary left


def test_page_holds_every_frame_and_fetches_nothing(drop_dir):
    from flexparcel.io.results import load_result

    out, _ = drop_dir
    text = (out / "view.html").read_text(encoding="utf-8")
    k = len(load_result(out / "results.npz")["time"])
    assert k >= 5
    # self-contained: plotly.js inline, no external script, stylesheet or fetch
    assert not re.search(r"<script[^>]*\bsrc\s*=", text, re.IGNORECASE)
    assert not re.search(r"<link[^>]*\bhref\s*=\s*[\"']?https?:", text, re.IGNORECASE)
    assert "cdn.plot.ly" not in text.split("</script>", 1)[0][:2000]
    assert "Plotly.newPlot" in text and len(text) > 3_000_000  # the bundle is embedded
    assert f'data-frame-count="{k}"' in text and f'data-total-frames="{k}"' in text
    data = _page_data(text)
    assert data["frames"] == list(range(k)) and len(data["time"]) == k
    names = {t["name"]: t for t in data["traces"]}
    assert set(names) == {"packaging", "contents"}
    for t in names.values():  # 16-bit positions of every vertex in every frame
        assert len(base64.b64decode(t["positions"])) == k * t["nv"] * 3 * 2
        assert len(base64.b64decode(t["fields"]["displacement"])) == k * t["nv"]
        assert len(base64.b64decode(t["fields"]["strain"])) == k * t["nc"]
    # the rigid content as its rounded box (segments=2: 6 patches of 6 x 6 points)
    assert names["contents"]["nv"] == 6 * 36
    fields = data["fields"]
    assert fields["displacement"]["available"] and fields["consignment"]["available"]
    assert fields["consignment"]["ticktext"] == ["small"]
    # a drop records no contact force: offered greyed out, with the reason
    assert not fields["contact_force"]["available"]
    assert "only the conveyor records" in fields["contact_force"]["why"]
    assert not fields["contact_pressure"]["available"]
    assert re.search(r'<option value="contact_force" disabled>', text)
    assert "Horizontal drop test, small" in text and "plate" in text


def test_positions_decode_to_the_results(drop_dir):
    from flexparcel.io.results import load_result

    out, _ = drop_dir
    data = _page_data((out / "view.html").read_text(encoding="utf-8"))
    res = load_result(out / "results.npz")
    t = next(t for t in data["traces"] if t["name"] == "packaging")
    q = np.frombuffer(base64.b64decode(t["positions"]), "<u2").reshape(-1, t["nv"], 3)
    p = np.asarray(data["lo"]) + q * np.asarray(data["scale"])
    last = res["positions"][-1]
    # every decoded vertex lies on a packaging node of the last frame, within a 16-bit step
    step = float(np.max(data["scale"]))  # one 16-bit quantum [m]
    d = np.min(np.linalg.norm(p[-1][:, None, :] - last[None, :, :], axis=2), axis=1)
    assert d.max() <= np.sqrt(3) * step and step < 1e-5


def test_budget_subsamples_frames_and_says_so(drop_dir, tmp_path):
    from flexparcel.viz.viewer import _fixed_bytes, _frame_bytes, load_scene, write_viewer

    out, _ = drop_dir
    scene = load_scene(out)
    k = len(scene.time)
    tight = (_fixed_bytes(scene) + 4.5 * _frame_bytes(scene)) / 1e6  # room for 4 frames
    page = write_viewer(out, tmp_path / "tight.html", max_mb=tight)
    text = page.read_text(encoding="utf-8")
    shown = int(re.search(r'data-frame-count="(\d+)"', text).group(1))
    assert shown == 4 < k
    assert f"subsampled: {shown} of {k} saved frames" in text
    assert page.stat().st_size <= tight * 1e6
    data = _page_data(text)
    assert data["frames"][0] == 0 and data["frames"][-1] == k - 1
    capped = write_viewer(out, tmp_path / "three.html", max_frames=3).read_text()
    assert 'data-frame-count="3"' in capped and "at most 3 frames asked" in capped


def test_choose_frames_keeps_first_and_last():
    from flexparcel.viz.viewer import choose_frames

    assert list(choose_frames(5, 10, 0, 1e6)) == [0, 1, 2, 3, 4]
    idx = choose_frames(281, 1000, 0, 50_000)  # room for 50 frames
    assert idx[0] == 0 and idx[-1] == 280 and len(idx) <= 50 and np.all(np.diff(idx) > 0)
    assert list(choose_frames(100, 10**9, 0, 1.0)) == [0, 99]  # never fewer than two


def test_view_command_writes_the_page(drop_dir, tmp_path, capsys):
    from flexparcel.cli import main

    out, _ = drop_dir
    target = tmp_path / "again.html"
    assert main(["view", str(out), "--out", str(target), "--max-frames", "4"]) == 0
    assert target.is_file() and 'data-frame-count="4"' in target.read_text()
    assert str(target) in capsys.readouterr().out


def test_view_command_errors_name_the_file(tmp_path, capsys):
    from flexparcel.cli import main

    missing = tmp_path / "nowhere"
    assert main(["view", str(missing)]) == 2
    err = capsys.readouterr().err
    assert f"{missing}: no such folder" in err and "Traceback" not in err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["view", str(empty)]) == 2
    err = capsys.readouterr().err
    assert f"{empty}: not a results folder (no results.npz" in err
    (empty / "results.npz").write_bytes(b"not a zip file")
    assert main(["view", str(empty)]) == 2
    err = capsys.readouterr().err
    assert f"{empty / 'results.npz'}: not a readable results file" in err
    assert "Traceback" not in err
    assert main(["view", str(empty), "--max-frames", "1"]) == 2
    assert "--max-frames must be >= 2" in capsys.readouterr().err


def test_viewer_writer_never_fails_a_run(tmp_path):
    # a scenario without results.npz gets no page; one whose results hold no mesh a warning
    from flexparcel.io.results import save_result
    from flexparcel.viz.viewer import viewer_writer

    assert viewer_writer(None, tmp_path) == {}

    class Frames:
        time = np.array([0.0, 0.1])
        positions = np.zeros((2, 3, 3))
        rotation_vectors = np.zeros((2, 3, 3))
        velocities = np.zeros((2, 3, 6))
        energies: dict = {}
        stats: dict = {}

    save_result(tmp_path / "results.npz", Frames())
    with pytest.warns(UserWarning, match="no mesh cells"):
        assert viewer_writer(None, tmp_path) == {}
    assert not (tmp_path / "view.html").exists()


# --------------------------------------------------------------------------- in a browser
def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


CHROMIUM = _chromium()
# software WebGL (SwiftShader): newer Chromium builds no longer fall back to it by themselves
BROWSER_FLAGS = ["--headless", "--disable-gpu", "--no-sandbox", "--enable-unsafe-swiftshader",
                 "--use-angle=swiftshader", "--hide-scrollbars", "--mute-audio",
                 "--disable-dev-shm-usage", "--virtual-time-budget=15000"]  # fmt: skip


@pytest.mark.skipif(CHROMIUM is None, reason="Chromium not found on PATH (chromium, "
                    "chromium-browser, google-chrome); make browser-test installs it")  # fmt: skip
def test_browser_renders_the_scene(drop_dir, tmp_path):
    from PIL import Image

    out, _ = drop_dir
    url = (out / "view.html").resolve().as_uri()
    home = {"HOME": str(tmp_path)}  # chromium's profile and crash dumps stay in the tmp dir
    dom = subprocess.run([CHROMIUM, *BROWSER_FLAGS, f"--user-data-dir={tmp_path / 'p1'}",
                          "--dump-dom", url], capture_output=True, text=True, timeout=180,
                         env=home)  # fmt: skip
    m = re.search(r'<div id="flexparcel-viewer"[^>]*>', dom.stdout)
    assert m, f"no viewer element in the rendered DOM; stderr: {dom.stderr[-2000:]}"
    tag = m.group(0)
    k = int(re.search(r'data-total-frames="(\d+)"', tag).group(1))
    assert f'data-frame-count="{k}"' in tag
    assert 'data-rendered="yes"' in tag, f"scene not drawn: {tag}"
    assert 'data-frame="0"' in tag  # the page's script drew frame 0 itself
    assert "<canvas" in dom.stdout  # plotly's WebGL scene
    # opened at another frame and field (per-cell strain, the categorical consignment colours)
    for anchor, frame, field in (("#frame=last&field=strain", k - 1, "strain"),
                                 ("#frame=2&field=consignment", 2, "consignment")):  # fmt: skip
        dom = subprocess.run([CHROMIUM, *BROWSER_FLAGS, f"--user-data-dir={tmp_path / 'p3'}",
                              "--dump-dom", url + anchor], capture_output=True, text=True,
                             timeout=180, env=home)  # fmt: skip
        tag = re.search(r'<div id="flexparcel-viewer"[^>]*>', dom.stdout).group(0)
        assert 'data-rendered="yes"' in tag and f'data-frame="{frame}"' in tag, tag
        assert f'data-field="{field}"' in tag, tag
    shot = tmp_path / "view.png"
    run = subprocess.run([CHROMIUM, *BROWSER_FLAGS, f"--user-data-dir={tmp_path / 'p2'}",
                          f"--screenshot={shot}", "--window-size=1200,800", url],
                         capture_output=True, text=True, timeout=180, env=home)  # fmt: skip
    assert shot.is_file(), f"no screenshot; stderr: {run.stderr[-2000:]}"
    with Image.open(shot) as im:
        assert im.size == (1200, 800)
        rgb = np.asarray(im.convert("RGB"), float)
    # the 3-D scene below the controls: not blank, and the mesh drawn in the field's colours
    # (the axes, grid and plate are grey; the colour scale's purple to yellow are not)
    scene = rgb[120:, :1000, :]  # the colour bar sits at the right edge
    assert scene.std() > 8.0, f"blank scene (pixel std {scene.std():.1f})"
    colours = {tuple(c) for c in (scene[::4, ::4] // 16).reshape(-1, 3).astype(int)}
    assert len(colours) > 20, f"only {len(colours)} colours: the mesh was not drawn"
    saturated = (scene.max(axis=2) - scene.min(axis=2)) > 40
    assert saturated.sum() > 500, "no coloured mesh in the screenshot"
