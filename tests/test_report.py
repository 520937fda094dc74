"""The run report: report.html is written by a run and by 'silodem plot', is self-contained,
and a headless Chromium renders it with its figures."""

from __future__ import annotations

import hashlib
import html
import html.parser
import os
import re
import shutil
import signal
import subprocess
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from measure_helpers import tiny_hopper_config
from reliability_helpers import signal_dropped_by_a_callback

from silodem.cli import main
from silodem.run import run_simulation
from silodem.silo.geometry import silo_shape

PAPER_FIGURES = ["fig2_coordination", "fig3a_horizontal_filling", "fig3b_vertical_filling",
                 "fig4_switch_zone_network", "fig5_force_network", "fig6_horizontal_discharge",
                 "fig7_switch_zone_evolution"]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "run"
    run_simulation(tiny_hopper_config(), out, progress=False)
    return out


def _imgs(html: str) -> list[str]:
    return re.findall(r"<img [^>]*src='data:image/png;base64,([A-Za-z0-9+/=]+)'", html)


def test_a_report_written_before_its_folder_is_renamed_names_no_gone_folder(run_dir,
                                                                            tmp_path):
    """A study's run writes its report in runs/.<id>.tmp-<uuid> and renames the folder once
    complete: the page named that temporary folder's results.h5, which no longer existed."""
    from silodem.report.html import write_report

    tmp = tmp_path / ".run.tmp-0123456789ab"
    shutil.copytree(run_dir, tmp)
    write_report(tmp)
    final = tmp.rename(tmp_path / "run")
    page = (final / "report.html").read_text(encoding="utf-8")
    assert ".tmp-" not in page and str(tmp_path) not in page
    assert "Results: results.h5 in this page's folder, status complete." in page


def test_run_writes_a_self_contained_report(run_dir):
    html = (run_dir / "report.html").read_text(encoding="utf-8")
    pngs = sorted(p.stem for p in (run_dir / "figures").glob("*.png"))
    assert len(_imgs(html)) == len(pngs) == html.count("<img ")
    for name in PAPER_FIGURES:
        assert name in pngs and f"id='{name}'" in html
    assert "switch-zone peak" in html and "Janssen" in html and "PLANAR" in html
    assert "src='http" not in html and "<script" not in html  # nothing to fetch or run
    assert "[silo]" in html  # the config
    # which results file, in what state, made the page
    # (named in the page's folder, not by a path: a study writes the report in a temporary
    # folder that is then renamed, and a run folder may be moved)
    assert "Results: results.h5 in this page's folder, status complete." in html
    # force-network snapshots of the frames (issue 8): end of filling, early/late discharge
    for view in ("end_of_filling", "early_discharge", "late_discharge"):
        assert f"id='network_{view}'" in html


def test_a_quick_run_report_says_what_a_quick_silo_is_for(run_dir, tmp_path):
    """A --quick run (its config named '<scenario>-quick') gets the caveat that its small silo
    checks a setup and its numbers are not the full-size silo's; a run of its own size not."""
    from silodem.report.html import quick_caveat

    copy = tmp_path / "q"
    shutil.copytree(run_dir, copy)
    with h5py.File(copy / "results.h5", "r+") as h5:
        text = h5.attrs["config_toml"]
        assert 'name = "tiny-hopper"' in text
        h5.attrs["config_toml"] = text.replace('name = "tiny-hopper"', 'name = "tiny-hopper-quick"')
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(copy)])
    assert exc.value.code == 0
    import html as html_module

    caveat = html_module.escape(quick_caveat(hopper=True))  # (tiny-hopper)
    assert "a hopper a few grains tall" in caveat
    assert "hopper" not in quick_caveat(hopper=False)
    assert caveat in (copy / "report.html").read_text(encoding="utf-8")
    assert caveat not in (run_dir / "report.html").read_text(encoding="utf-8")


def test_a_report_names_what_its_config_changed_from_the_scenario_it_is_named_after(
        tmp_path, monkeypatch):
    """A flat silo made from paper-case2 with --set showed case 2's description ('Cell +
    hopper silo ...') and nothing else: the report now lists the keys that differ from the
    scenario (or its --quick variant), in the schema's order; none for the scenario itself
    or for a config of another name. The scenario is the embedded one, whatever file of its
    name the working folder holds."""
    from silodem.report.html import description_html
    from silodem.scenario_files import changes_from_scenario, load_config, quick_variant

    sets = ['discharge.gate_speed=0.3', 'silo.kind="flat"', "seed=5"]
    cfg = load_config("paper-case2", sets)
    expected = ["seed = 5", 'silo.kind = "flat"', "discharge.gate_speed = 0.3"]
    assert changes_from_scenario(cfg) == ("paper-case2", expected)
    assert changes_from_scenario(quick_variant(cfg)) == ("paper-case2", expected)
    assert changes_from_scenario(quick_variant(load_config("paper-case2"))) == (
        "paper-case2", [])
    unset = load_config("paper-case2", ["material.restitution=0.5",
                                        "material.damping_ratio=0.2"])
    assert changes_from_scenario(unset)[1] == ["material.restitution = unset",
                                               "material.damping_ratio = 0.2"]
    assert changes_from_scenario(cfg.model_copy(update={"name": "mine"})) is None
    # the description is then said to be the scenario's (a stiffened case 1 opened with its
    # "grains overlap by about their radius" as fact)
    case2 = html.escape(load_config("paper-case2").description)
    assert description_html(quick_variant(cfg)) == (
        f"<p>The scenario paper-case2 --quick, after which this run's config is named: {case2}"
        "</p><p>This run differs from it in: seed = 5; silo.kind = &quot;flat&quot;; "
        "discharge.gate_speed = 0.3; where the description speaks of these, it is the "
        "scenario's, not this run's.</p>")
    case1 = load_config("paper-case1")
    assert description_html(case1) == f"<p>{html.escape(case1.description)}</p>"
    # a description changed too is named (the line had called it the scenario's), and is
    # the config's own
    mine = load_config("paper-case2", ['description="my flat test"', "seed=5"])
    assert changes_from_scenario(mine)[1] == ['description = "my flat test"', "seed = 5"]
    assert description_html(mine) == (
        "<p>my flat test</p><p>This run's config is named after the scenario paper-case2 and "
        "differs from it in: description = &quot;my flat test&quot;; seed = 5.</p>")
    # a list on one line (tomli_w's several lines read 'material.radii = [ 0.09, 0.11, ]')
    radii = load_config("paper-case2", ['material.radius_distribution="discrete"',
                                        "material.radii=[0.09, 0.11]"])
    assert changes_from_scenario(radii)[1] == ['material.radius_distribution = "discrete"',
                                               "material.radii = [0.09, 0.11]"]
    monkeypatch.chdir(tmp_path)  # a file named as the scenario here is not the scenario
    (tmp_path / "paper-case2").write_text("not TOML at all", encoding="utf-8")
    assert changes_from_scenario(cfg) == ("paper-case2", expected)


def test_a_run_no_real_silo_has_gets_a_box_saying_so_at_the_top():
    """paper-case1 --quick: 2256 kg/m^3 from grains of 1607, and 71 of 166 grains lost through
    the walls; its key numbers were shown as a sound run's. A bulk density above the grains'
    own, or more than 5 % of the grains lost, puts a box at the top; a sound run has none."""
    from types import SimpleNamespace

    from silodem.report.html import unphysical_html

    def analysis(rho_b, poured, lost):
        cfg = SimpleNamespace(material=SimpleNamespace(density=1607.0))
        events = {"n_poured": poured, "lost_count": lost}
        return SimpleNamespace(res=SimpleNamespace(cfg=cfg, events=events), rho_b=rho_b)

    box = unphysical_html(analysis(2256.0, 166, 71))
    assert box.startswith("<p class='unfinished' id='unphysical'>Not a physical packing: its "
                          "bulk density, 2256 kg/m^3, is above the grains&#x27; own 1607; 71 "
                          "of its 166 grains (43 %) were lost through the walls.")
    assert "bulk density" not in unphysical_html(analysis(1300.0, 166, 68))
    assert unphysical_html(analysis(1300.0, 166, 8)) == ""  # 4.8 %: under 5 %
    assert "9 of its 166 grains (5 %)" in unphysical_html(analysis(1300.0, 166, 9))
    assert unphysical_html(analysis(float("nan"), 0, 0)) == ""


def test_flat_silo_report_speaks_of_its_floor_not_a_hopper(tmp_path):
    """A flat-bottomed silo: the report has no hopper angle and no wedge-hopper paragraph, and
    Fig. 2's axis reaches the largest coordination number measured (it was cut at 6.5)."""
    from silodem.report import figures_stress as fs
    from silodem.report.analysis import analyse
    from silodem.report.load import load_results

    cfg = tiny_hopper_config()
    cfg = cfg.model_copy(update={"name": "tiny-flat",
                                 "silo": cfg.silo.model_copy(update={"kind": "flat"})})
    run_simulation(cfg, tmp_path, progress=False)
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "flat bottom" in html
    assert "hopper angle" not in html and "PLANAR" not in html
    a = analyse(load_results(tmp_path))
    m = a.res.group("measure")
    peak = max(np.nanmax(m["band"]["coordination"]), np.nanmax(m["circles"]["coordination"]))
    fig = fs.fig_coordination(a)
    for ax in fig.axes:
        assert ax.get_ylim()[1] >= peak
    # the cycles' time along the top: cycles x dt
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    (seconds,) = fig.axes[0].child_axes
    assert seconds.get_xlabel() == "time [s]"
    np.testing.assert_allclose(seconds.get_xlim(),
                               np.array(fig.axes[0].get_xlim()) * a.res.attrs["dt"], rtol=1e-12)
    label = fs.fig_horizontal(a, "fill").axes[0].get_xlabel()
    assert label == "horizontal stress sigma_h on the wall [Pa]"
    _assert_bottom_load(a, ("left_floor", "right_floor", "gate"))


def _assert_bottom_load(a, bottom: tuple[str, ...]) -> None:
    """The key number's load on the bottom after filling (the binned wall pressures, averaged
    over the last measure.window of settling) is the vertical force the bottom's wall contacts
    of the settled state exert, within 2 % (a fill at rest); and, Newton's law at rest, all
    the walls' contacts together carry the fill's weight m g within 1 %.  The row gives the
    share of that weight."""
    with h5py.File(a.res.folder / "results.h5") as h5:
        names = [n.decode() for n in h5["walls/name"][()]]
        wall, fy = h5["settled/wall_contacts/wall"][()], h5["settled/wall_contacts/fy"][()]
        radius = h5["settled/particles/radius"][()]
    m = a.res.cfg.material
    weight = float(np.sum(m.density * np.pi * radius**2 * m.thickness)) * a.res.cfg.gravity
    on_bottom = float(fy[np.isin(wall, [names.index(n) for n in bottom])].sum())
    assert fy.sum() == pytest.approx(weight, rel=0.01)
    assert a.bottom[0] == pytest.approx(on_bottom, rel=0.02)
    row = next(v for q, v, _ in a.numbers if q.startswith("load on "))
    share = 100 * a.bottom[0] / (float(a.res.events["initial_mass"]) * a.res.cfg.gravity)
    assert row == f"{a.bottom[0]:,.0f} ({share:.3g} %)"
    # a run without discharge has no initial_mass: the share is of the settled grains' weight
    # (it was left out), the same weight summed above from their radii
    import copy as shallow
    import dataclasses

    from silodem.report.key_numbers import add_numbers

    b = shallow.copy(a)
    b.res = dataclasses.replace(a.res, events={k: v for k, v in a.res.events.items()
                                               if k != "initial_mass"})
    b.numbers = []
    add_numbers(b)
    row = next(v for q, v, _ in b.numbers if q.startswith("load on "))
    assert row == f"{a.bottom[0]:,.0f} ({100 * a.bottom[0] / weight:.3g} %)"


def test_the_closed_gate_carries_what_the_hopper_walls_do_not(run_dir):
    from silodem.report.analysis import analyse
    from silodem.report.load import load_results

    _assert_bottom_load(analyse(load_results(run_dir)), ("gate",))


def test_plot_re_renders_from_results_without_running(run_dir, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(run_dir, copy)
    shutil.rmtree(copy / "figures")
    for name in ("report.html", "settled.png", "final.png"):
        (copy / name).unlink()
    digest = hashlib.sha256((copy / "results.h5").read_bytes()).hexdigest()
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(copy)])
    assert exc.value.code == 0
    assert (copy / "report.html").is_file()
    assert len(list((copy / "figures").glob("*.png"))) == len(list(
        (run_dir / "figures").glob("*.png")))
    assert hashlib.sha256((copy / "results.h5").read_bytes()).hexdigest() == digest
    # the run drew its pictures from results.h5 as plot does: the same bytes
    for name in ("settled.png", "final.png"):
        assert (copy / name).read_bytes() == (run_dir / name).read_bytes()


def test_interrupt_while_drawing_loses_nothing_and_says_so(tmp_path, monkeypatch, capsys):
    """Ctrl-C after results.h5 is written (while the pictures are drawn): one line, exit 130,
    results.h5 complete, no temporary file left, and 'silodem plot' draws what is missing."""
    import h5py

    import silodem.output
    from silodem.scenario_files import config_to_toml

    config = tmp_path / "tiny.toml"
    config.write_text(config_to_toml(tiny_hopper_config()), encoding="utf-8")
    out = tmp_path / "run"
    draw_state = silodem.output.draw_state
    drawn = []

    def draw_then_interrupt(*args, **kwargs):
        if drawn:  # the second picture: the user presses Ctrl-C inside the PNG writer
            raise KeyboardInterrupt
        drawn.append(draw_state(*args, **kwargs))

    monkeypatch.setattr(silodem.output, "draw_state", draw_then_interrupt)
    with pytest.raises(SystemExit) as exc:
        main(["run", str(config), "--out", str(out)])
    assert exc.value.code == 130
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]  # after the progress bar
    assert last.startswith("interrupted: after the run's results") and "Traceback" not in err
    assert f"silodem plot {out}" in last
    with h5py.File(out / "results.h5", "r") as h5:
        assert h5.attrs["status"] == "complete"
    assert (out / "settled.png").is_file() and not (out / "final.png").exists()
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]
    monkeypatch.setattr(silodem.output, "draw_state", draw_state)
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(out)])
    assert exc.value.code == 0
    assert (out / "final.png").is_file() and (out / "report.html").is_file()


def test_plot_ends_with_130_when_a_callback_drops_the_ctrl_c(run_dir, tmp_path, monkeypatch,
                                                             capsys):
    """A Ctrl-C's KeyboardInterrupt raised inside a weakref callback while matplotlib draws is
    dropped by Python, and the drawing goes on (seen in the run's drawing: exit 0 in 2 of 30
    tries). 'silodem plot' notes the signal and still ends with the one line and 130."""
    import silodem.output

    copy = tmp_path / "copy"
    shutil.copytree(run_dir, copy)
    write_views = silodem.output.write_views

    def drawing_that_drops_the_interrupt(out):
        signal_dropped_by_a_callback(signal.SIGINT)
        write_views(out)

    monkeypatch.setattr(silodem.output, "write_views", drawing_that_drops_the_interrupt)
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(copy)])
    assert exc.value.code == 130
    assert capsys.readouterr().err.strip().splitlines() == ["interrupted"]


@pytest.mark.parametrize("what", ["missing", "empty", "garbage", "the file", "a device"])
def test_plot_of_a_bad_folder_is_one_line_and_exit_2(what, tmp_path, capsys):
    folder = tmp_path / "x"
    if what not in ("missing", "a device"):
        folder.mkdir()
    if what == "a device":  # /dev/null was "no such directory", though it exists
        folder = Path(os.devnull)
    if what in ("garbage", "the file"):
        (folder / "results.h5").write_text("not hdf5")
    if what == "the file":  # results.h5 itself given: it was "no such directory"
        folder = folder / "results.h5"
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(folder)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and str(folder) in err
    if what == "the file":
        assert "is a file; give the results folder" in err
    if what in ("missing", "a device"):
        said = {"missing": "no such folder", "a device": "not a folder"}[what]
        assert err == f"error: {folder} is not a results folder ({said})\n", err


def test_plot_of_a_damaged_results_file_is_one_line_and_exit_2(run_dir, tmp_path, capsys):
    """4000 bytes overwritten at one place or another inside results.h5: h5py fails in many
    ways (OSError, RuntimeError, UnicodeDecodeError, or a None where a group was: a TypeError
    traceback before), or reads nothing damaged.  Each is one line and exit 2, or a report."""
    folder = tmp_path / "x"
    folder.mkdir()
    size = (run_dir / "results.h5").stat().st_size
    refused = 0
    for offset in range(2048, size - 4000, size // 12):
        shutil.copy(run_dir / "results.h5", folder / "results.h5")
        with open(folder / "results.h5", "r+b") as f:
            f.seek(offset)
            f.write(b"\xff" * 4000)
        with pytest.raises(SystemExit) as exc:
            main(["plot", str(folder)])
        err = capsys.readouterr().err
        assert exc.value.code in (0, 2) and "Traceback" not in err, (offset, err)
        if exc.value.code == 2:
            assert err.count("\n") == 1 and str(folder) in err, (offset, err)
            refused += 1
    assert refused >= 6  # most places hold metadata or compressed data that h5py checks


def test_plot_with_a_config_file_that_is_not_text_is_one_line(run_dir, tmp_path, capsys):
    """results.h5 without its config, beside a config.toml that is not UTF-8 text: a
    UnicodeDecodeError traceback before."""
    folder = tmp_path / "x"
    folder.mkdir()
    shutil.copy(run_dir / "results.h5", folder / "results.h5")
    with h5py.File(folder / "results.h5", "r+") as h5:
        del h5.attrs["config_toml"]
    (folder / "config.toml").write_bytes(b"\x84\xff\x00 not text")
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(folder)])
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert err.count("\n") == 1 and "config.toml" in err


def _edit_config_attr(h5):
    h5.attrs["config_toml"] = 7


def _shorten_stress(h5):
    data = h5["measure/circles/stress"][:10]
    del h5["measure/circles/stress"]
    h5["measure/circles/stress"] = data


def _slices_as_text(h5):  # valid shapes, but a figure cannot use the numbers
    data = h5["measure/profiles/slices"][()]
    del h5["measure/profiles/slices"]
    h5["measure/profiles/slices"] = data.astype("S8")


def _no_dt(h5):
    del h5.attrs["dt"]


def _no_walls(h5):
    del h5["walls"]


def _shorten_a_timeseries_column(h5):
    data = h5["timeseries/time"][:5]
    del h5["timeseries/time"]
    h5["timeseries/time"] = data


@pytest.mark.parametrize("damage, needle", [(_edit_config_attr, "config_toml"),
                                            (_shorten_stress, "/measure/circles/stress"),
                                            (_slices_as_text, "could not be drawn"),
                                            (_no_dt, "no attribute dt"),
                                            (_no_walls, "no /walls"),
                                            (_shorten_a_timeseries_column,
                                             "/timeseries/time has 5 rows")])
def test_plot_of_a_results_file_edited_inconsistently_is_one_line(run_dir, tmp_path, capsys,
                                                                  damage, needle):
    """Valid HDF5 with wrong contents (an AttributeError, IndexError or other traceback
    before, from the figures): one line naming the problem, exit 2."""
    folder = tmp_path / "x"
    folder.mkdir()
    shutil.copy(run_dir / "results.h5", folder / "results.h5")
    with h5py.File(folder / "results.h5", "r+") as h5:
        damage(h5)
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(folder)])
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err and needle in err, err

def test_plot_on_a_full_disk_says_so_not_that_the_results_are_bad(run_dir, tmp_path, capsys,
                                                                   monkeypatch):
    """A system error while writing stays a system error (a catch-all had blamed results.h5)."""
    import errno

    import silodem.report.html

    folder = tmp_path / "x"
    shutil.copytree(run_dir, folder)

    def full(path, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(silodem.report.html, "write_atomic", full)
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(folder)])
    err = capsys.readouterr().err
    assert exc.value.code == 1 and err.count("\n") == 1, err  # (2 is bad input)
    assert "No space left on device" in err and "could not be drawn" not in err


def test_plot_of_a_run_with_no_measurement_sample(tmp_path, monkeypatch):
    """measure.interval longer than the run: not one sample.  The report is drawn without the
    measurements (it failed on an empty time array, during the run and in 'silodem plot').
    Such an interval is refused before a run now (``checks.check_schedule``), let through here:
    a results file without a sample still comes from a run stopped before its first one."""
    import silodem.silo.checks

    monkeypatch.setattr(silodem.silo.checks, "check_schedule", lambda cfg: None)
    run_simulation(tiny_hopper_config().model_copy(update={"measure": tiny_hopper_config(
        interval=1e6).measure}), tmp_path, progress=False)
    with h5py.File(tmp_path / "results.h5", "r") as h5:
        assert h5["measure/time"].shape == (0,)  # not one sample
    for _ in range(2):  # as the run wrote it, then as 'silodem plot' draws it again
        page = (tmp_path / "report.html").read_text(encoding="utf-8")
        assert "No measurements in this results file" in page
        figures = set(re.findall(r"<figure id='([^']+)'", page))
        # the force networks come from the snapshots; the measured figures are left out
        assert {"fig4_switch_zone_network", "fig5_force_network"} <= figures
        assert not figures & {"fig2_coordination", "fig7_switch_zone_evolution",
                              "fig3a_horizontal_filling", "stress_fields"}
        (tmp_path / "report.html").unlink()
        with pytest.raises(SystemExit) as exc:
            main(["plot", str(tmp_path)])
        assert exc.value.code == 0


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _headless(*args: str) -> str:
    """stdout of headless chromium run with ``args`` (a fresh profile, nothing fetched)."""
    browser = _chromium()
    if browser is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed in CI (.ci/run installs it)")
        pytest.skip("chromium not installed")
    profile = tempfile.mkdtemp(prefix="chromium-profile-")
    try:
        return subprocess.run(
            [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking", "--disable-component-update",
             "--disable-sync", f"--user-data-dir={profile}", *args],
            check=True, capture_output=True, text=True, timeout=120).stdout
    finally:
        shutil.rmtree(profile, ignore_errors=True)


def test_chromium_renders_the_report_with_its_figures(run_dir, tmp_path):
    shot = tmp_path / "shot.png"
    _headless("--hide-scrollbars", "--window-size=1200,12000", f"--screenshot={shot}",
              (run_dir / "report.html").resolve().as_uri())
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)[..., :3]
    assert img.shape[0] >= 11000  # (the page's top: key numbers, then figures)
    # not blank: the page has text and pictures
    assert img.std() > 0.05
    # the figures are drawn: coloured pixels (text and tables are grey) all down the page
    sat = img.max(axis=2) - img.min(axis=2)
    coloured = sat > 0.25
    assert coloured.mean() > 0.01
    rows = np.flatnonzero(coloured.any(axis=1))
    assert rows.max() - rows.min() > 4000


PHONE_PX = 400  # a phone's width in CSS pixels


def test_the_report_fits_a_phone_s_width(run_dir, tmp_path):
    """At 400 px the key numbers' and the events' tables ran 17 and 26 px past the page's
    right edge (long words: switch_centre, discharge_end_reason), and a phone laid the page
    out at desktop width without a viewport (an audit).  Chromium lays the page out in a
    frame 400 px wide (headless, it lays out no window under 500 px) and measures how far its
    widest element reaches: no further than the page's own width."""
    page = tmp_path / "report.html"
    shutil.copy(run_dir / "report.html", page)
    assert "<meta name='viewport' content='width=device-width, initial-scale=1'>" in \
        page.read_text(encoding="utf-8")
    frame = tmp_path / "phone.html"
    frame.write_text(
        f"<html><body style='margin:0'><iframe id=f src='report.html' style='width:{PHONE_PX}px;"
        "height:1500px;border:0'></iframe><script>document.getElementById('f').onload="
        "function(){var d=document.getElementById('f').contentDocument.documentElement;"
        "document.body.setAttribute('data-widths',d.scrollWidth+' '+d.clientWidth);}"
        "</script></body></html>", encoding="utf-8")
    dom = _headless("--allow-file-access-from-files", "--window-size=1200,2000",
                    "--virtual-time-budget=5000", "--dump-dom", frame.resolve().as_uri())
    found = re.search(r'data-widths="(\d+) (\d+)"', dom)
    assert found, dom[-300:]
    scroll, client = map(int, found.groups())
    assert client <= PHONE_PX and scroll <= client, (scroll, client)


class _Figures(html.parser.HTMLParser):
    """(figure id, img alt, figcaption text) of a page's figures."""

    def __init__(self) -> None:
        super().__init__()
        self.found: list[list[str]] = []
        self._caption = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "figure":
            self.found.append([a.get("id", ""), "", ""])
        elif tag == "img" and self.found:
            self.found[-1][1] = a.get("alt", "")
        self._caption = self._caption or tag == "figcaption"

    def handle_endtag(self, tag):
        self._caption = self._caption and tag != "figcaption"

    def handle_data(self, data):
        if self._caption:
            self.found[-1][2] += data


def test_every_figure_s_alt_text_says_what_it_shows(run_dir):
    """A screen reader read each figure's file name ("fig2 underscore coordination"): the alt
    text is now the first clause of the caption that follows, what the figure shows."""
    from silodem.report.html import ALT_CHARS, alt_text

    parser = _Figures()
    parser.feed((run_dir / "report.html").read_text(encoding="utf-8"))
    assert len(parser.found) == len(_imgs((run_dir / "report.html").read_text("utf-8")))
    for name, alt, caption in parser.found:
        caption = re.sub(r"^Fig\. \w+ equivalent\. ", "", caption)
        assert alt and not alt.startswith(name), (name, alt)
        assert alt == alt_text(caption) and len(alt) <= ALT_CHARS + 4
        assert caption.startswith(alt.removesuffix(" ...")), (alt, caption)
    assert alt_text("Wall friction along the wall: its value; more. End.") == (
        "Wall friction along the wall")
    assert alt_text("C_n (eq. 10) in time. The band") == "C_n (eq. 10) in time"
    assert alt_text("One clause.") == "One clause"
    assert alt_text("Stress (time average: window), more") == "Stress"  # (no open parenthesis)
    long = "word " * 60
    assert alt_text(long) == ("word " * 29 + "word ...") and len(alt_text(long)) <= ALT_CHARS + 4


# Machado, Oliveira & Fernandes (2009), IEEE TVCG 15, 1291: linear-RGB matrices of
# protanopia and deuteranopia, severity 1
PROTANOPIA = np.array([[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216],
                       [-0.003882, -0.048116, 1.051998]])
DEUTERANOPIA = np.array([[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
                         [-0.011820, 0.042940, 0.968881]])


def _as_seen(color, vision: np.ndarray) -> np.ndarray:
    """sRGB [0, 1] of ``color`` as a reader with that colour vision sees it (sRGB's
    transfer curve, IEC 61966-2-1, around the matrix)."""
    from matplotlib.colors import to_rgb

    c = np.array(to_rgb(color))
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    seen = np.clip(vision @ lin, 0.0, 1.0)
    return np.where(seen <= 0.0031308, 12.92 * seen, 1.055 * seen ** (1 / 2.4) - 0.055)


def test_the_circles_keep_one_style_that_every_colour_vision_tells_apart(run_dir):
    """Fig. 7 drew the left, centre and right circles blue, green and red, all solid: to a
    deuteranope green and red lie 0.12 apart in sRGB (Machado et al. 2009), and Fig. 2 gave
    the same circles other colours (an audit).  Each circle now has one colour and marker in
    both figures, and the three circles' colours lie at least 0.3 apart in every vision."""
    from silodem.report import figures_stress as fs
    from silodem.report.analysis import analyse
    from silodem.report.load import load_results

    a = analyse(load_results(run_dir))
    names = [str(n) for n in a.res.group("measure", "circles")["name"]]
    styles = {}
    for fig in (fs.fig_coordination(a), fs.fig_evolution(a)):
        for ax in fig.axes:
            for line in ax.get_lines():
                name = line.get_label().split(":")[0]
                if name in names:
                    styles.setdefault(name, set()).add((line.get_color(), line.get_marker()))
    assert sorted(styles) == sorted(names) and len(names) == 3
    assert all(len(s) == 1 for s in styles.values()), styles  # one style a circle
    (colors, markers) = zip(*(next(iter(styles[n])) for n in names), strict=True)
    assert len(set(markers)) == 3 and "None" not in markers  # told apart without colour too
    for vision in (np.eye(3), PROTANOPIA, DEUTERANOPIA):
        seen = [_as_seen(c, vision) for c in colors]
        gaps = [np.linalg.norm(seen[i] - seen[j]) for i in range(3) for j in range(i + 1, 3)]
        assert min(gaps) > 0.3, (vision, gaps)
    old = [_as_seen(c, DEUTERANOPIA) for c in ("#2ca02c", "#d62728")]
    assert np.linalg.norm(old[0] - old[1]) < 0.15  # the green and red that were used


def test_grain_disks_widen_the_axes_to_the_whole_disks():
    """The disks of the report's pictures are one EllipseCollection, whose own data limits are
    its centres: two disks of radius 0.5 m at x = 0 and 1 m span x from -0.5 to 1.5 m."""
    import matplotlib.pyplot as plt

    from silodem.report.draw import grain_disks

    fig, ax = plt.subplots()
    grain_disks(ax, {"x": np.array([0.0, 1.0]), "y": np.array([0.0, 0.0]),
                     "radius": np.array([0.5, 0.5])})
    assert ax.dataLim.bounds == pytest.approx((-0.5, -0.5, 2.0, 1.0))
    plt.close(fig)


def test_a_ratio_axis_says_where_it_cuts_the_curves():
    """sigma_h / sigma_v axes end at 3; a ratio drawn above that (4.5 here, NaN and inf from
    an empty zone ignored) is named in the panel, and nothing is written when all fit."""
    import matplotlib.pyplot as plt

    from silodem.report.draw import ratio_axis

    fig, (cut, fits) = plt.subplots(1, 2)
    ratio_axis(cut, [0.5, np.nan, 4.5], [np.inf, 1.0])
    ratio_axis(fits, [0.5, 2.9])
    assert cut.get_ylim() == (0.0, 3.0) and fits.get_ylim() == (0.0, 3.0)
    assert [t.get_text() for t in cut.texts] == ["axis cut at 3: values up to 4.5"]
    assert len(fits.texts) == 0
    near, just = plt.subplots()  # a value just above the cut: "values up to 3" said it was not
    ratio_axis(just, [1.0, 3.0004])
    assert [t.get_text() for t in just.texts] == ["axis cut at 3: values up to 3.0004"]
    plt.close(fig)
    plt.close(near)


def test_field_maps_paint_only_the_inside_of_the_silo(run_dir):
    """The field cells cut by a hopper wall hold the value of their inside part; the maps are
    clipped to the silo's outline, whose area (shoelace formula) is the silo's area from the
    trapezoid of hopper and the rectangle of cell: ((B + D)/2) z_j + B (H - z_j)."""
    from matplotlib.collections import QuadMesh

    from silodem.report import figures_stress as fs
    from silodem.report.analysis import analyse
    from silodem.report.load import load_results

    a = analyse(load_results(run_dir))
    cfg = a.res.cfg
    s = cfg.silo
    outline = np.array(silo_shape(cfg).outline())
    x, z = outline[:, 0], outline[:, 1]
    shoelace = 0.5 * (np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1)))
    expected = (0.5 * (s.cell_width + s.outlet_width) * s.hopper_height
                + s.cell_width * (s.wall_height - s.hopper_height))
    assert shoelace == pytest.approx(expected, rel=1e-12)
    flat = silo_shape(cfg.model_copy(update={"silo": s.model_copy(update={"kind": "flat"})}))
    assert flat.outline() == [(0.0, 0.0), (s.cell_width, 0.0), (s.cell_width, s.wall_height),
                              (0.0, s.wall_height)]
    maps = [ax for ax in fs.fig_fields(a).axes if ax.get_xlabel() == "x [m]"]  # no colour bars
    meshes = [c for ax in maps for c in ax.collections if isinstance(c, QuadMesh)]
    assert len(meshes) == 6
    for mesh in meshes:
        path, _ = mesh.get_clip_path().get_transformed_path_and_affine()
        np.testing.assert_allclose(path.vertices[:len(outline)], outline)


def _legend_covers(fig) -> list[str]:
    """Labels of the curves with a drawn point inside a legend's box (display pixels)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    boxes = [leg.get_window_extent(renderer) for leg in legends]
    def inside(box, xy):
        return ((xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1)
                & (xy[:, 1] >= box.y0) & (xy[:, 1] <= box.y1))

    hidden = []
    for ax in fig.axes:
        clip = ax.get_window_extent(renderer)
        for line in ax.get_lines():
            xy = np.asarray(line.get_xydata(), dtype=float)
            xy = line.get_transform().transform(xy[np.isfinite(xy).all(axis=1)])
            xy = xy[inside(clip, xy)]  # drawn, not clipped away
            if any(inside(b, xy).any() for b in boxes):
                hidden.append(line.get_label())
    return hidden


def test_legends_of_the_stress_and_contact_figures_hide_no_data(run_dir):
    """Figs. 2, 3a, 3b, 6 and 7 carry up to 14 legend entries; inside the axes the legend lay
    over data (Fig. 7's sigma_v plateau of settling, the stress points near the surface, Fig. 2's
    end of discharge).  No drawn point of any curve may fall inside a legend's box."""
    from silodem.report import figures_stress as fs
    from silodem.report.analysis import analyse
    from silodem.report.load import load_results

    a = analyse(load_results(run_dir))
    figs = {"fig2": fs.fig_coordination(a), "fig3a": fs.fig_horizontal(a, "fill"),
            "fig3b": fs.fig_vertical(a, "fill"), "fig6": fs.fig_horizontal(a, "discharge"),
            "vertical_discharge": fs.fig_vertical(a, "discharge"), "fig7": fs.fig_evolution(a)}
    for name, fig in figs.items():
        assert fig is not None, name
        assert fig.legends or any(ax.get_legend() for ax in fig.axes), name
        assert _legend_covers(fig) == [], name


def test_vertical_stress_during_discharge_draws_that_windows_strips(run_dir):
    """The vertical-stress figure of the discharge window draws that window's near-wall and
    cross-section sigma_zz, with the near-wall profile after filling in grey, and names the
    window's times."""
    from silodem.report import figures_stress as fs
    from silodem.report.analysis import analyse
    from silodem.report.load import load_results

    a = analyse(load_results(run_dir))
    ax = fs.fig_vertical(a, "discharge").axes[0]
    lines = {line.get_label(): line for line in ax.get_lines()}
    dis, fill = a.strips["discharge"], a.strips["fill"]
    near = lines["sigma_zz near the walls (Love-Weber strips)"]
    np.testing.assert_array_equal(near.get_xdata(), dis["near_zz"])
    np.testing.assert_array_equal(near.get_ydata(), dis["z"])
    np.testing.assert_array_equal(lines["sigma_zz, mean over the cross-section"].get_xdata(),
                                  dis["slice_zz"])
    grey = lines[f"sigma_zz near the walls, {a.labels['fill']}"]
    np.testing.assert_array_equal(grey.get_xdata(), fill["near_zz"])
    t0, t1 = a.windows["discharge"]
    assert ax.get_title().endswith(f"{a.labels['discharge']} (t = {t0:.2f}-{t1:.2f} s)")


def test_settled_and_final_pictures_have_a_force_colour_bar(run_dir, monkeypatch, tmp_path):
    """settled.png / final.png colour the chains by the normal force: without a colour bar the
    colours said nothing a reader could use."""
    import silodem.report.draw
    from silodem.output import draw_state
    from silodem.report.load import load_results

    saved, save = [], silodem.report.draw.save_png

    def keep(fig, target):
        saved.append(fig)
        save(fig, target)

    monkeypatch.setattr(silodem.report.draw, "save_png", keep)
    res = load_results(run_dir, only=("walls", "settled"))
    draw_state(res.snapshot("settled"), res.group("walls"), tmp_path / "s.png", "settled")
    labels = [ax.get_ylabel() for ax in saved[0].axes]
    assert "normal contact force F_n [N]" in labels


def test_settled_picture_frames_the_silo_at_any_size(run_dir, monkeypatch, tmp_path):
    """Margins of a fixed 0.3-0.5 m put a silo 0.2 m wide in a seventh of settled.png: the
    same silo and grains scaled by 0.05 or 20 are framed alike, the axes' limits scaled by
    the same factor (the picture of a similar silo is similar), the walls spanning most of
    either axis and every grain inside them."""
    import silodem.report.draw
    from silodem.output import draw_state
    from silodem.report.load import load_results

    saved, save = [], silodem.report.draw.save_png
    monkeypatch.setattr(silodem.report.draw, "save_png",
                        lambda fig, target: (saved.append(fig), save(fig, target)))
    res = load_results(run_dir, only=("walls", "settled"))
    snap = res.snapshot("settled")
    limits = {}
    for scale in (1.0, 0.05, 20.0):
        p = dict(snap["particles"])
        for key in ("x", "y", "radius"):
            p[key] = np.asarray(p[key], dtype=float) * scale
        walls = {k: np.asarray(v) * scale if k in ("ax", "ay", "bx", "by") else v
                 for k, v in res.group("walls").items()}
        draw_state({**snap, "particles": p}, walls, tmp_path / "s.png", "scaled")
        ax = saved[-1].axes[0]
        (x0, x1), (z0, z1) = limits[scale] = ax.get_xlim(), ax.get_ylim()
        wx = np.concatenate([walls["ax"], walls["bx"]])
        wz = np.concatenate([walls["ay"], walls["by"]])
        assert np.ptp(wx) > 0.7 * (x1 - x0) and np.ptp(wz) > 0.7 * (z1 - z0)
        assert x0 <= wx.min() and wx.max() <= x1 and z0 <= (p["y"] - p["radius"]).min()
        assert (p["y"] + p["radius"]).max() <= z1
    for scale in (0.05, 20.0):
        np.testing.assert_allclose(limits[scale], np.multiply(limits[1.0], scale), rtol=1e-6)


def test_the_run_events_table_gives_each_event_its_meaning_and_unit(run_dir):
    """The events table showed raw attribute names and bare numbers (initial_mass 4074.7):
    every event a run writes, and every one docs/output.md lists, has its meaning and unit."""
    from pathlib import Path

    from silodem.report.html import EVENT_MEANINGS

    with h5py.File(run_dir / "results.h5", "r") as h5:
        written = set(h5["events"].attrs)
    doc = (Path(__file__).parents[1] / "docs" / "output.md").read_text(encoding="utf-8")
    row = next(line for line in doc.splitlines() if line.startswith("| `/events`"))
    listed = set(re.findall(r"`([a-z_]+)`", row.split("|")[4]))
    assert written and written <= listed == set(EVENT_MEANINGS)
    html = (run_dir / "report.html").read_text(encoding="utf-8")
    for name in written:
        assert f"<td>{name}</td>" in html and EVENT_MEANINGS[name] in html


def test_figures_left_out_for_lack_of_data_are_named(run_dir, tmp_path):
    """A figure whose data the run lacks was dropped from report.html without a word (Fig. 8
    of a run whose discharge window got no sample; the three network snapshots of a
    results.h5 copied without its frames/).  The page now names what it left out."""
    import html as html_module

    from silodem.report.analysis import analyse
    from silodem.report.html import FIGURES, build_html, render_figures
    from silodem.report.load import load_results

    a = analyse(load_results(run_dir))
    figures = render_figures(a, tmp_path / "figures")
    assert [spec.name for spec, _ in figures] == [spec.name for spec in FIGURES]
    page = build_html(a, [f for f in figures if f[0].name != "fig8_change"])
    assert ("Left out for lack of data in this run: fig8_change (Fig. 8) (the key numbers' "
            "n/a rows and the warnings say what is missing).") in html_module.unescape(page)
    assert "Left out: network_end_of_filling, network_early_discharge, network_late_discharge;"\
        in page  # no snapshots given
    copy = tmp_path / "copy"
    shutil.copytree(run_dir, copy)
    shutil.rmtree(copy / "frames")
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(copy)])
    assert exc.value.code == 0
    page = (copy / "report.html").read_text(encoding="utf-8")
    assert "Left out: network_end_of_filling, network_early_discharge, network_late_discharge;"\
        in page and "Left out for lack of data" not in page


def _ink_at_the_edges(png: Path) -> float:
    """The darkest pixel's distance below white (0-255) in the outermost 2 px of a PNG: text
    cut by the picture's edge leaves ink there; a figure's white margin none."""
    from matplotlib.image import imread

    img = imread(png)[..., :3]  # (floats in 0..1)
    edges = np.concatenate([img[:2].reshape(-1, 3), img[-2:].reshape(-1, 3),
                            img[:, :2].reshape(-1, 3), img[:, -2:].reshape(-1, 3)])
    return float(255 * (1.0 - edges.min()))


def test_no_title_or_label_is_cut_by_a_pictures_edge(tmp_path):
    """A study's runs have long names: their settled.png title ran off the left edge
    ('aper-study-theta35_...'); and a steep (75 deg) hopper's tall switch-zone zoom had its
    panel titles cut at the top of fig4.  Every picture's outer 2 px stay white."""
    from silodem.scenario_files import load_config, quick_variant

    cfg = quick_variant(load_config("paper-case2", [
        "silo.hopper_angle_from_horizontal_deg=75", "walls.friction_deg=10",
        "silo.wall_height=8.5", "fill.n_particles=480",  # (paper-study's [set])
        "name='paper-study-theta75_phiG20_phiP10_seed2'"]))
    out = tmp_path / "run"
    run_simulation(cfg, out, progress=False)
    pictures = [out / "settled.png", out / "final.png", *sorted((out / "figures").glob("*.png"))]
    assert out / "figures" / "fig4_switch_zone_network.png" in pictures
    assert {p.name: _ink_at_the_edges(p) for p in pictures} == {p.name: 0.0 for p in pictures}
