"""Figures of a plan: four valid, non-blank PNGs for game and rigid results, inf-tolerant."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.image import imread

import staghunt
from staghunt import plots

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
NAMES = ["paths_3d.png", "top_view.png", "altitude.png", "convergence.png"]


def tiny_plan(method: str, scenario: str = "scenario2", seed: int = 0) -> staghunt.PlanResult:
    s = staghunt.load_scenario(scenario)
    return staghunt.plan(s, method=method, seed=seed,
                         settings=s.solver.with_(particles=20, iterations=5, waypoints=10))


@pytest.fixture(scope="module")
def game_result() -> staghunt.PlanResult:
    return tiny_plan("game")


@pytest.fixture(scope="module")
def rigid_result() -> staghunt.PlanResult:
    return tiny_plan("rigid", scenario="scenario1", seed=1)


def assert_valid_pngs(paths: list[Path], out_dir: Path) -> None:
    assert [p.name for p in paths] == NAMES
    for p in paths:
        assert p.parent == out_dir
        assert p.read_bytes()[:8] == PNG_SIGNATURE
        img = imread(p)
        assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
        assert float(img[..., :3].var()) > 0.0, f"{p.name} is blank"
    leftovers = sorted(q.name for q in out_dir.iterdir() if q.name not in NAMES)
    assert leftovers == [], f"temporary files left behind: {leftovers}"


def test_save_figures_game(game_result: staghunt.PlanResult, tmp_path: Path) -> None:
    out = tmp_path / "figs" / "game"  # created on demand
    paths = plots.save_figures(game_result, out, dpi=60)
    assert_valid_pngs(paths, out)


def test_save_figures_rigid_with_leader(rigid_result: staghunt.PlanResult, tmp_path: Path) -> None:
    assert rigid_result.leader_path is not None
    paths = plots.save_figures(rigid_result, tmp_path, dpi=60)
    assert_valid_pngs(paths, tmp_path)
    # the virtual leader appears, dashed, in the 3-D and top views
    for make in (plots.plot_paths_3d, plots.plot_top_view):
        fig = make(rigid_result)
        leader = [ln for ln in fig.axes[0].get_lines() if ln.get_label() == "virtual leader"]
        assert len(leader) == 1 and leader[0].get_linestyle() == "--"


def test_history_with_inf(rigid_result: staghunt.PlanResult, tmp_path: Path) -> None:
    history = np.array(rigid_result.history, dtype=float)
    history[:3, 0] = np.inf  # becomes finite at iteration 3
    history[:, 2] = np.inf  # never finite
    objective = np.array(rigid_result.objective_history, dtype=float)
    objective[:2] = np.inf
    broken = dataclasses.replace(rigid_result, history=history, objective_history=objective)

    fig = plots.plot_convergence(broken)
    ax = fig.axes[0]
    assert ax.get_ylabel() == "ln J_n"
    curves = {ln.get_label().split(":")[0]: ln for ln in ax.get_lines()}
    y = np.asarray(curves["UAV1"].get_ydata(), dtype=float)
    assert np.all(np.isnan(y[:3])) and np.all(np.isfinite(y[3:]))
    assert np.allclose(y[3:], np.log(history[3:, 0]))
    assert any("never finite" in ln.get_label() for ln in ax.get_lines())
    assert "first finite at iteration 2" in ax.get_title()
    assert "finite from iteration 3" in curves["UAV1"].get_label()

    paths = plots.save_figures(broken, tmp_path, dpi=60)
    assert_valid_pngs(paths, tmp_path)


def test_all_infinite_history(game_result: staghunt.PlanResult, tmp_path: Path) -> None:
    inf = np.full_like(np.asarray(game_result.history, dtype=float), np.inf)
    broken = dataclasses.replace(game_result, history=inf, objective_history=inf.copy())
    assert_valid_pngs(plots.save_figures(broken, tmp_path, dpi=50), tmp_path)


def test_figures_are_labelled_and_coloured_consistently(game_result: staghunt.PlanResult) -> None:
    names = game_result.uav_names
    makers = (plots.plot_paths_3d, plots.plot_top_view, plots.plot_altitude, plots.plot_convergence)
    for make in makers:
        fig = make(game_result)
        assert isinstance(fig, Figure)
        ax = fig.axes[0]
        assert game_result.scenario.name in ax.get_title()
        assert game_result.method in ax.get_title()
        assert ax.get_xlabel() and ax.get_ylabel()
        legends = [ax.get_legend(), *fig.legends]
        texts = [t.get_text() for lg in legends if lg is not None for t in lg.get_texts()]
        for n, name in enumerate(names):
            assert any(t.startswith(name) for t in texts), f"{name} missing from {make.__name__}"
            lines = [ln for ln in ax.get_lines() if ln.get_label().startswith(name)]
            assert lines and lines[0].get_color() == plots.uav_colour(n)
    units = plots.plot_top_view(game_result).axes[0]
    assert units.get_xlabel() == "x (m)" and units.get_ylabel() == "y (m)"


def test_overwrites_atomically_and_keeps_old_file_on_failure(
    game_result: staghunt.PlanResult, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = plots.save_figures(game_result, tmp_path, dpi=40)
    before = first[0].read_bytes()
    plots.save_figures(game_result, tmp_path, dpi=50)  # replacing works
    assert first[0].read_bytes() != before
    kept = first[0].read_bytes()

    def boom(self: Figure, *args: object, **kwargs: object) -> None:
        raise RuntimeError("disk full")

    monkeypatch.setattr(Figure, "savefig", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        plots.save_figures(game_result, tmp_path)
    assert first[0].read_bytes() == kept
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(NAMES)


def test_no_global_matplotlib_state(game_result: staghunt.PlanResult, tmp_path: Path) -> None:
    backend = matplotlib.get_backend()
    rc = dict(matplotlib.rcParams)
    plots.save_figures(game_result, tmp_path, dpi=40)
    assert matplotlib.get_backend() == backend
    assert dict(matplotlib.rcParams) == rc


def test_rejects_bad_dpi(game_result: staghunt.PlanResult, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="dpi"):
        plots.save_figures(game_result, tmp_path, dpi=0)


def test_equilibria_title_fits_its_figure(game_result: staghunt.PlanResult) -> None:
    """The equilibria figure's title (a plan's long one) lies within the figure, not cut at
    either end."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from staghunt.plots.common import _title
    from staghunt.plots.equilibria import EquilibriaPanel, equilibria_figure

    J = np.array([[10738.4, 792.6, 2952.6], [10717.6, 981.7, 2992.5], [10894.9, 1931.4, 2513.9]])
    panel = EquilibriaPanel(_title(game_result, "Equilibria found"), J, np.array([False, False, False]),
                            J[:1], tuple(game_result.uav_names))
    fig = equilibria_figure([panel])
    FigureCanvasAgg(fig).draw()
    box = fig.axes[0].title.get_window_extent()
    assert 0 <= box.x0 and box.x1 <= fig.bbox.x1 and box.y1 <= fig.bbox.y1
