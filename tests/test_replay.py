"""Outputs of a flight: the offline 3-D replay page (checked in a real chromium, network cut off),
the five flight figures and the GIF animation."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from staghunt.plots.animation import flight_animation
from staghunt.plots.flight import flight_figures
from staghunt.plots.replay import replay_data, replay_html, write_replay_html

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FIGURES = ["flight_3d.png", "flight_top.png", "flight_altitude.png", "flight_tracking.png",
           "flight_separation.png"]
T = 60


def synthetic_flight(n_samples: int = T, n_uavs: int = 3) -> dict[str, Any]:
    """3 UAVs crossing a 100 x 100 x 40 m site; a truck (cylinder) appears at sample 25 and
    drives north; a crane jib (polygon, z 25-27 m) turns over the middle; two replans."""
    t = np.linspace(0.0, 29.5, n_samples)
    s = t / t[-1]
    uavs = []
    for n in range(n_uavs):
        y0 = 25.0 + 25.0 * n
        actual = np.stack([10 + 80 * s, y0 + 4 * np.sin(2 * np.pi * s), 10 + 5 * n + 3 * s], axis=1)
        reference = actual + (1 + n) * np.stack([0.3 * np.cos(5 * s + n), 0.2 * np.sin(3 * s), 0.1 * s], axis=1)
        uavs.append({"name": f"UAV{n + 1}", "radius": 1.0, "actual": actual.tolist(),
                     "reference": reference.tolist()})
    visible = (np.arange(n_samples) >= n_samples * 25 // 60).tolist()
    truck = np.stack([np.full(n_samples, 60.0), 10 + 50 * s], axis=1)
    angle = 0.8 * s
    arm = np.array([[-20, -1], [20, -1], [20, 1], [-20, 1]], dtype=float)
    rot = np.stack([np.stack([np.cos(angle), -np.sin(angle)], -1),
                    np.stack([np.sin(angle), np.cos(angle)], -1)], -2)  # (T, 2, 2)
    jib = np.einsum("tij,vj->tvi", rot, arm) + np.array([50.0, 50.0])
    return {
        "title": "synthetic </script><b>flight</b> · seed 1",
        "site": {"xmin": 0, "xmax": 100, "ymin": 0, "ymax": 100, "zmin": 0, "zmax": 40},
        "times": t.tolist(),
        "uavs": uavs,
        "cylinders": [[30.0, 40.0, 5.0], [75.0, 80.0, 4.0]],
        "prisms": [
            {"polygon": [[35, 70], [45, 70], [45, 85], [35, 85]], "base": 0.0, "top": 22.0, "nofly": False},
            {"polygon": [[80, 5], [95, 5], [95, 20], [80, 20]], "base": -1e9, "top": 1e9, "nofly": True},
        ],
        "moving": [
            {"name": "truck", "kind": "cylinder", "radius": 3.0, "xy": truck.tolist(), "visible": visible},
            {"name": "jib", "kind": "polygon", "base": 25.0, "top": 27.0, "polygons": jib.tolist(),
             "visible": [True] * n_samples},
        ],
        "replans": [{"time": 12.7, "trigger": "sensed pop-up 1", "verdict": "epsilon-equilibrium"},
                    {"time": 20.0, "trigger": "truck <close>", "verdict": "feasible"}],
        "terrain": None,
        "separation_limit": 8.0,
    }


@pytest.fixture(scope="module")
def flight() -> dict[str, Any]:
    return synthetic_flight()


# --------------------------------------------------------------------------------------------
# the page, as text
# --------------------------------------------------------------------------------------------


def embedded(page: str) -> dict[str, Any]:
    m = re.search(r'<script type="application/json" id="flight-data">(.*?)</script>', page, re.S)
    assert m is not None
    return json.loads(m.group(1))


def test_html_is_offline_and_embeds_the_data(flight: dict[str, Any], tmp_path: Path) -> None:
    page = replay_html(flight)
    assert "http://" not in page and "https://" not in page
    assert not re.search(r"""(src|href|action)\s*=\s*["']?\s*(\w+:)?//""", page, re.I)
    assert not re.search(r"@import|url\(", page)
    assert page.count("</script>") == 2  # the title's "</script>" is escaped
    assert "&lt;/script&gt;&lt;b&gt;flight" in page  # and shown as text
    data = embedded(page)
    assert data["times"] == pytest.approx(flight["times"], abs=1e-3)
    assert [u["name"] for u in data["uavs"]] == ["UAV1", "UAV2", "UAV3"]
    actual = np.asarray(data["uavs"][1]["actual"]).reshape(-1, 3)
    assert np.allclose(actual, flight["uavs"][1]["actual"], atol=0.0051)
    assert data["moving"][0]["visible"][:25] == [0] * 25 and data["moving"][0]["visible"][25] == 1
    nofly = data["prisms"][1]
    assert (nofly["base"], nofly["top"], nofly["nofly"]) == (0.0, 40.0, True)  # clipped to the site
    assert [r["frame"] for r in data["replans"]] == [25, 40]  # samples at or before 12.7 s, 20 s

    target = tmp_path / "replay.html"
    write_replay_html(target, flight)
    assert target.read_text(encoding="utf-8") == page
    assert [p.name for p in tmp_path.iterdir()] == ["replay.html"]


def test_long_flights_are_subsampled() -> None:
    long = synthetic_flight(n_samples=3001, n_uavs=2)
    data = replay_data(long)
    assert len(data["times"]) == 1500
    assert data["times"][0] == 0.0 and data["times"][-1] == pytest.approx(29.5)
    assert len(data["uavs"][0]["actual"]) == 3 * 1500
    assert len(data["moving"][1]["polygons"]) == 1500
    assert len(replay_html(long)) < 400_000


def test_bad_shapes_are_reported(flight: dict[str, Any]) -> None:
    broken = dict(flight, uavs=[dict(flight["uavs"][0], actual=flight["uavs"][0]["actual"][:-1])])
    with pytest.raises(ValueError, match=r"UAV1\.actual has shape \(59, 3\), expected \(60, 3\)"):
        replay_html(broken)


# --------------------------------------------------------------------------------------------
# the page, in a browser
# --------------------------------------------------------------------------------------------


def chromium_executable() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("no chromium executable on PATH (CI installs Debian's chromium)")
    return exe


def test_replay_in_browser(flight: dict[str, Any], tmp_path: Path) -> None:
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    exe = chromium_executable()
    target = tmp_path / "replay.html"
    write_replay_html(target, flight)
    url = target.as_uri()

    requests: list[str] = []
    messages: list[str] = []
    errors: list[str] = []

    def route(r: Any) -> None:
        if r.request.url == url:
            r.continue_()
        else:
            requests.append(r.request.url)
            r.abort()

    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=["--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 800})
            page.route("**/*", route)
            page.on("console", lambda m: messages.append(f"{m.type}: {m.text}")
                    if m.type in ("error", "warning") else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url)
            page.wait_for_function("() => window.staghuntReplay !== undefined")
            api = "window.staghuntReplay"
            assert page.evaluate(f"{api}.frameCount()") == T
            assert page.evaluate(f"{api}.time()") == 0.0

            def positions() -> tuple[list[list[float]], list[list[float]]]:
                return (page.evaluate(f"{api}.uavPositions()"),
                        page.evaluate(f"{api}.uavScreenPositions()"))

            site0, screen0 = positions()
            expected0 = [u["actual"][0] for u in flight["uavs"]]
            assert np.allclose(site0, expected0, atol=0.01)

            slider = page.locator("input#time")
            assert slider.get_attribute("type") == "range"
            slider.fill("37")
            slider.dispatch_event("input")
            site1, screen1 = positions()
            assert page.evaluate(f"{api}.time()") == pytest.approx(flight["times"][37], abs=1e-3)
            assert np.allclose(site1, [u["actual"][37] for u in flight["uavs"]], atol=0.01)
            assert len(screen1) == 3 and all(s is not None for s in screen1)
            moved = np.linalg.norm(np.asarray(screen1) - np.asarray(screen0), axis=1)
            assert np.all(moved > 5.0), moved  # every dot moved on screen
            assert f"38/{T}" in page.locator("#time-label").inner_text()

            # each dot is drawn where the API says, in its UAV's colour
            colours = page.evaluate(  # one read-back of the whole canvas
                """(pts) => { const c = document.getElementById('view'), d = window.devicePixelRatio || 1;
                   const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
                   return pts.map(([x, y]) => { const i = 4 * (Math.round(y * d) * c.width + Math.round(x * d));
                                               return Array.from(px.slice(i, i + 4)); }); }""",
                screen1)
            data = embedded(target.read_text(encoding="utf-8"))
            for rgba, u in zip(colours, data["uavs"]):
                want = [int(u["colour"][i:i + 2], 16) for i in (1, 3, 5)]
                assert np.abs(np.asarray(rgba[:3]) - want).max() <= 8, (u["name"], rgba, want)

            # setTime picks the nearest frame; the slider follows
            assert page.evaluate(f"{api}.setTime(12.8)") == pytest.approx(flight["times"][26])
            assert slider.input_value() == "26"
            assert np.allclose(page.evaluate(f"{api}.uavPositions()"),
                               [u["actual"][26] for u in flight["uavs"]], atol=0.01)

            # play advances time, pause stops it; a drag orbits the view
            page.click("#play")
            page.wait_for_function(f"{api}.frame() > 26")
            page.click("#play")
            assert page.locator("#play").inner_text() == "Play"
            before = page.evaluate(f"{api}.uavScreenPositions()")
            box = page.locator("#view").bounding_box()
            assert box is not None
            page.mouse.move(box["x"] + 300, box["y"] + 300)
            page.mouse.down()
            page.mouse.move(box["x"] + 380, box["y"] + 320, steps=4)
            page.mouse.up()
            page.mouse.wheel(0, 200)
            assert page.evaluate(f"{api}.uavScreenPositions()") != before
        finally:
            browser.close()
    assert requests == []
    assert messages == []
    assert errors == []


# --------------------------------------------------------------------------------------------
# figures and animation
# --------------------------------------------------------------------------------------------


def test_flight_figures(flight: dict[str, Any], tmp_path: Path) -> None:
    out = tmp_path / "figs"
    paths = flight_figures(flight, out)
    assert [p.name for p in paths] == FIGURES
    for p in paths:
        assert p.parent == out
        data = p.read_bytes()
        assert len(data) > 5000 and data[:8] == PNG_SIGNATURE
    assert sorted(q.name for q in out.iterdir()) == sorted(FIGURES)  # nothing left behind


def test_flight_figures_single_uav_no_obstacles(tmp_path: Path) -> None:
    lone = synthetic_flight(n_samples=20, n_uavs=1)
    lone.update(moving=[], replans=[], cylinders=[], prisms=[])
    lone.pop("separation_limit")
    assert len(flight_figures(lone, tmp_path)) == 5


def test_flight_animation(flight: dict[str, Any], tmp_path: Path) -> None:
    from PIL import Image

    gif = flight_animation(flight, tmp_path / "flight.gif", fps=10, max_frames=25)
    assert gif == tmp_path / "flight.gif"
    with Image.open(gif) as im:
        assert im.format == "GIF"
        assert im.n_frames == 25
    assert [p.name for p in tmp_path.iterdir()] == ["flight.gif"]  # no temporary file left
    short = flight_animation(synthetic_flight(n_samples=12), tmp_path / "short.gif", max_frames=200)
    with Image.open(short) as im:
        assert im.n_frames == 12  # never more frames than samples
