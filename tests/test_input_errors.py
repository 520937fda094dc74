"""Bad input is refused with exit code 2 and one line naming what is wrong, never a traceback.

Complements tests/test_config_cli.py (unknown keys, malformed TOML, missing file, unknown
scenario, bad --set, bad --threads): limits and non-finite numbers, files that are not tables,
folders and --out paths, --resume misuse, values that are valid one by one but give no usable
run, and fuzzing of whole TOML files and of the numbers a run is built from.
"""

from __future__ import annotations

import datetime as dt
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import tomllib
import warnings
from pathlib import Path

import h5py
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from silodem.checkpoint import FORMAT
from silodem.cli import main
from silodem.config import Config
from silodem.errors import InputError, schema_keys
from silodem.scenario_files import config_to_toml, load_config
from silodem.silo.checks import check_numbers
from silodem.silo.procedure import SiloRun


def refused(capsys, *args: str, silent: bool = False) -> str:
    """Run the command line in process; assert exit code 2 and one line; return the line.
    ``silent``: also assert that nothing was printed on stdout (no work was announced)."""
    with pytest.raises(SystemExit) as exit_info:
        main(list(args))
    captured = capsys.readouterr()
    assert exit_info.value.code == 2, captured.err
    assert "Traceback" not in captured.err + captured.out
    assert not (silent and captured.out), captured.out
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].strip(), captured.err
    return lines[0]


def assert_names(line: str, *needles: str) -> None:
    for needle in needles:
        assert needle in line, line


# --- values --------------------------------------------------------------------------------


def test_too_many_grains_is_refused_naming_the_limit(capsys):
    line = refused(capsys, "show", "--set", "fill.n_particles=20000000")
    assert_names(line, "fill.n_particles", "10000000")


def test_a_stop_fraction_above_1_needs_reinsertion(capsys):
    """Without re-insertion at most the whole mass leaves: stop_fraction = 1.5 could never be
    reached (the run would go on to max_time); with it the mass passes more than once."""
    line = refused(capsys, "show", "--set", "discharge.stop_fraction=1.5")
    assert_names(line, "discharge.stop_fraction (1.5) above 1 needs discharge.reinsert = true")
    line = refused(capsys, "show", "--set", "discharge.stop_fraction=1001", "--set",
                   "discharge.reinsert=true")
    assert_names(line, "discharge.stop_fraction", "1000")
    cfg = load_config("paper-case2", ["discharge.stop_fraction=1.5", "discharge.reinsert=true"])
    assert cfg.discharge.stop_fraction == 1.5


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "+inf"])
@pytest.mark.parametrize("key", ["material.kn", "time.dt", "gravity"])
def test_non_finite_numbers_are_refused(capsys, key, value):
    line = refused(capsys, "show", "--set", f"{key}={value}")
    assert_names(line, key, "finite")


def test_non_finite_number_in_a_file_is_refused(capsys, tmp_path):
    text = config_to_toml(load_config("paper-case2"))
    path = tmp_path / "inf.toml"
    path.write_text(text.replace("\nkn = ", "\nkn = inf # ", 1))
    assert_names(refused(capsys, "show", str(path)), "material.kn", "finite")


@pytest.mark.parametrize(
    "replacement",
    ["material = 3", 'material = "soft"', "[[material]]\nkn = 1", "material = [1, 2]"],
)
def test_a_section_that_is_not_a_table_is_refused(capsys, tmp_path, replacement):
    text = config_to_toml(load_config("paper-case2"))
    head, _, rest = text.partition("[material]")
    rest = rest[rest.index("\n[") :]  # drop the [material] table
    path = tmp_path / "section.toml"
    path.write_text(f"{head}{replacement}\n{rest}")
    assert_names(refused(capsys, "show", str(path)), "material: a section, not a value",
                 "[material]")


def test_a_files_several_mistakes_are_all_named_in_its_line(capsys, tmp_path):
    """Three mistakes in a file gave the first and "(+2 more)": the user mended them one
    rerun at a time without knowing where the others were."""
    text = config_to_toml(load_config("paper-case2"))
    text = text.replace("\nfriction_deg = ", "\nmu = ", 1)  # unknown (and so one missing)
    text = text.replace("\nseed = ", "\nsed = ", 1)  # unknown, and seed missing
    path = tmp_path / "three.toml"
    path.write_text(text)
    line = refused(capsys, "show", str(path))
    assert line.startswith("config error: unknown key"), line
    assert_names(line, "(+3 more: ", "unknown", "seed missing", "friction_deg missing")
    assert_names(line, *(f"{key}" for key in ("material.mu", "sed")))


def test_a_set_of_a_whole_section_names_its_keys(capsys):
    """`--set silo=3` gave pydantic's "Input should be a valid dictionary or instance of
    Silo"."""
    line = refused(capsys, "show", "paper-case2", "--set", "silo=3")
    assert_names(line, "--set silo=3", "'silo' is a section", "cell_width", "silo.kind=")


def test_a_set_that_breaks_a_sections_check_is_named(capsys):
    """The check of radius_max >= radius_min belongs to [material]: the --set that broke it
    was not named, although the message names its key."""
    line = refused(capsys, "show", "paper-case2", "--set", "material.radius_min=0.2")
    assert line.endswith("(from --set material.radius_min=0.2)"), line


@pytest.mark.parametrize("sets, first", [
    (["material.radius_max=2"], "silo.outlet_width (1.0) must exceed the largest grain"),
    (["silo.cell_width=1e6"], "silo.wall_height (6.0) must exceed the hopper height"),
    (["measure.circle_x=[1,2]", "seed=3"], "measurement circles need all four lists"),
    (["silo.cell_width=8", "silo.hopper_angle_from_horizontal_deg=60", "seed=3"],
     "silo.wall_height (6.0) must exceed the hopper height 6.062 m")])
def test_a_set_that_breaks_a_check_across_keys_is_named(capsys, tmp_path, sets, first):
    """A --set that broke a check of other keys (a grain wider than the outlet: the message
    names silo.outlet_width) was not named. The config without the --set values is valid, so
    they are: those that break it alone (not seed=3), or where only together they do (a cell
    8 m wide and a hopper at 60 deg reach above the walls: each alone passes), those without
    which the rest pass. A file's own mistake is not put on them."""
    args = [a for item in sets for a in ("--set", item)]
    line = refused(capsys, "show", "paper-case2", *args)
    assert line.startswith(f"config error: {first}")
    named = [item for item in sets if item != "seed=3"]
    assert line.endswith(f"(after --set {', '.join(named)})"), line
    bad = tmp_path / "bad.toml"  # invalid before any --set: the file is named, not the sets
    text = config_to_toml(load_config("paper-case2"))
    text, count = re.subn(r"^radius_max = 0\.11\b", "radius_max = 2.0", text,
                          flags=re.MULTILINE)
    assert count == 1
    bad.write_text(text, encoding="utf-8")
    line = refused(capsys, "show", str(bad), "--set", "seed=3")
    assert "must exceed the largest grain" in line and line.endswith(f"(in {bad})"), line


def test_empty_measurement_circles_are_refused(capsys):
    """Four empty circle lists were accepted: a run without circles, whose report and study
    table have no switch-zone stresses to show."""
    args = [a for key in ("names", "x", "z", "radius")
            for a in ("--set", f"measure.circle_{key}=[]")]
    line = refused(capsys, "show", "paper-case2", *args)
    assert_names(line, "circle_radius are empty", "at least one circle", "default three")


@pytest.mark.parametrize("sets, first, named", [
    (["discharge.clog_time=0.01", "seed=3"], "discharge.clog_time = 0.01 s is shorter",
     ["discharge.clog_time=0.01"]),
    (["time.safety=0.4", "fill.initial_speed=300", "seed=3"],
     "fill.initial_speed = 300 m/s carries a poured grain 0.143 m",
     ["time.safety=0.4", "fill.initial_speed=300"])])
def test_a_set_that_makes_values_unusable_together_is_named(capsys, tmp_path, sets, first,
                                                            named):
    """`run`'s checks of values that make no run together (silo.checks.check_numbers) did not
    name the --set that broke a config that runs without them. A clog time shorter than a
    grain's fall is its own --set's; 300 m/s carries a poured grain 300 x 0.000476 = 0.143 m
    in a step at time.safety 0.4 (dt = 0.4 dt_crit, dt_crit = 1.19e-3 s), more than the
    0.09 m radius, but 0.071 m at the default 0.2: only together do they break it. A file's
    own such mistake is not put on a --set."""
    args = [a for item in sets for a in ("--set", item)]
    line = refused(capsys, "run", "paper-case2", *args, "--out", str(tmp_path / "r"))
    assert line.startswith(f"error: {first}"), line
    assert line.endswith(f"(after --set {', '.join(named)})"), line
    assert not (tmp_path / "r").exists()  # refused before any folder is made
    bad = tmp_path / "bad.toml"
    text = config_to_toml(load_config("paper-case2"))
    text, count = re.subn(r"^clog_time = 2\.0\b", "clog_time = 0.01", text, flags=re.MULTILINE)
    assert count == 1
    bad.write_text(text, encoding="utf-8")
    line = refused(capsys, "run", str(bad), "--set", "seed=3", "--out", str(tmp_path / "r"))
    assert line.startswith("error: discharge.clog_time = 0.01 s is shorter"), line
    assert "after --set" not in line


def test_a_set_key_with_an_empty_part_and_a_toml_date_are_named_as_written(capsys, tmp_path):
    """`--set .kn=1` was refused as the unknown key '""', and a TOML date given for a number
    was quoted as Python's datetime.date(1979, 5, 27)."""
    for item in (".kn=1", "material..kn=1", "material.=1"):
        line = refused(capsys, "show", "--set", item)
        key = item.partition("=")[0]
        assert line == (f"error: --set '{item}': the key '{key}' has an empty part (write "
                        "dotted.key=value, e.g. --set material.kn=2e7)")
    when = tmp_path / "when.toml"
    when.write_text("seed = 1979-05-27\n", encoding="utf-8")
    assert "seed: Input should be a valid integer (got the date 1979-05-27)" in refused(
        capsys, "show", str(when))
    when.write_text("seed = 07:32:00\n", encoding="utf-8")
    assert "(got the time 07:32:00)" in refused(capsys, "show", str(when))


def test_a_quoted_dotted_key_is_named_as_written(capsys, tmp_path):
    """'"settle.threshold" = 0.01' is one key named settle.threshold at the top level (TOML):
    the message said "unknown key 'settle.threshold' (did you mean 'settle.threshold'?)"."""
    text = config_to_toml(load_config("paper-case2"))
    path = tmp_path / "quoted.toml"
    path.write_text('"settle.threshold" = 0.01\n' + text)
    assert_names(refused(capsys, "show", str(path)), "unknown key '\"settle.threshold\"'",
                 "write settle.threshold without quotes")


def test_a_config_files_errors_name_the_file(capsys, tmp_path):
    """An empty file gave "missing required key 'seed' ... (+4 more)" without saying which
    file, or that it was empty; a value out of range in a file did not name it either."""
    empty = tmp_path / "empty.toml"
    empty.write_text("")
    assert refused(capsys, "show", str(empty)).endswith(f"(in {empty}, an empty file)")
    bad = tmp_path / "bad.toml"
    bad.write_text(config_to_toml(load_config("paper-case2")).replace(
        "\nseed = ", "\nseed = -", 1))
    line = refused(capsys, "show", str(bad))
    assert line.startswith("config error: seed:") and line.endswith(f"(in {bad})")


def test_a_file_that_is_not_toml_at_all_is_refused(capsys, tmp_path):
    path = tmp_path / "binary.toml"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00")
    assert_names(refused(capsys, "show", str(path)), "binary.toml")


@pytest.mark.parametrize("content, needle", [
    ("x = " + "[" * 5000 + "]" * 5000, "nested too deeply"),  # a RecursionError before
    ("seed = " + "9" * 5000, "4300 digits"),  # Python's int limit, a ValueError before
])
@pytest.mark.parametrize("command", ["show", "sweep"])
def test_toml_that_python_cannot_read_is_refused(capsys, tmp_path, content, needle, command):
    path = tmp_path / "odd.toml"
    path.write_text(content)
    assert_names(refused(capsys, command, str(path)), "odd.toml", needle)


def test_a_byte_order_mark_is_not_a_toml_error(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_text("\ufeff" + config_to_toml(load_config("paper-case2")), encoding="utf-8")
    assert load_config(str(path)) == load_config("paper-case2")


@pytest.mark.parametrize("name", ["/tmp/elsewhere", "..", ".", "a\nb", "a\\b", "", "  ",
                                  "a" * 201, "\u00e9" * 101])
def test_a_name_that_cannot_name_the_results_folder_is_refused(capsys, name):
    """The default results folder is runs/<name>: a name with '/' wrote anywhere, '..' into
    the current folder; a blank one made 'studies/  -quick'; one of more than 200 bytes
    (a folder name may have 255) failed only when the folder was made, blamed on --out
    (201 bytes: 201 ASCII letters or 101 e-acutes of 2 bytes each)."""
    line = refused(capsys, "show", "--set", f"name={tomli_w.dumps({'v': name})[4:].strip()}")
    assert_names(line, "name")
    if len(name.encode()) > 200:
        assert f"name is {len(name.encode())} bytes long; at most 200" in line


def test_the_last_of_two_sets_of_a_key_is_blamed(capsys):
    line = refused(capsys, "show", "--set", "fill.n_particles=12",
                   "--set", "fill.n_particles=abc")
    assert_names(line, "(from --set fill.n_particles=abc)")


@pytest.mark.parametrize("seeds", ["[true]", '["1"]', "[2.0]"])
def test_study_seeds_are_integers_not_converted(capsys, tmp_path, seeds):
    path = tmp_path / "study.toml"
    path.write_text(f'base = "paper-case2"\nseeds = {seeds}\n[grid]\n"material.friction_deg" '
                    "= [20.0]\n")
    assert_names(refused(capsys, "sweep", str(path), "--out", str(tmp_path / "o")), "seeds")


@pytest.mark.parametrize("x, radius, needle", [(0.6, 1e300, "larger than the silo"),
                                               (100.0, 0.2, "no part inside")])
def test_a_measurement_circle_outside_the_silo_is_refused_before_the_run(capsys, tmp_path, x,
                                                                          radius, needle):
    """A radius of 1e300 m overflowed the circle's area mid-run (an OverflowError); a circle
    far outside measured nothing.  Refused before any folder is made."""
    sets = ["measure.circle_names=[\"a\"]", f"measure.circle_x=[{x}]",
            "measure.circle_z=[0.3]", f"measure.circle_radius=[{radius}]"]
    out = tmp_path / "r"
    line = refused(capsys, "run", "--quick", "--out", str(out),
                   *[arg for s in sets for arg in ("--set", s)])
    assert_names(line, "circle 'a'", needle)
    assert not out.exists()


@pytest.mark.parametrize("name, needle", [
    ("band", "'band' is the junction band's name"),  # its columns replaced the band's (api)
    (" ", "must not be empty"),
])
def test_circle_names_that_clash_or_are_blank_are_refused(capsys, name, needle):
    sets = [f"measure.circle_names=[\"{name}\"]", "measure.circle_x=[1.5]",
            "measure.circle_z=[0.6]", "measure.circle_radius=[0.3]"]
    assert_names(refused(capsys, "show", *[arg for s in sets for arg in ("--set", s)]),
                 "measure.circle_names", needle)


def test_restitution_and_damping_ratio_together_are_refused(capsys):
    """damping_ratio replaced a given restitution without a word."""
    line = refused(capsys, "show", "--set", "material.damping_ratio=0.3",
                   "--set", "material.restitution=0.7")
    assert_names(line, "material.restitution", "material.damping_ratio", "give one")


def test_bench_without_untimed_steps_is_refused(capsys):
    """--settle 0 timed the kernels' compilation and the first list build (1.2 M against
    44 M particle-steps/s with --settle 1)."""
    assert_names(refused(capsys, "bench", "--n", "100", "--settle", "0"), "--settle",
                 "from 1", "compile")


@pytest.mark.parametrize("flag", ["--steps", "--settle"])
def test_bench_step_counts_beyond_64_bits_are_refused(capsys, flag):
    assert_names(refused(capsys, "bench", "--n", "100", flag, "9" * 23), "--steps", "--settle")


def test_a_study_given_to_run_and_a_scenario_given_to_sweep_are_named(capsys, tmp_path):
    assert_names(refused(capsys, "run", "paper-study"), "is a study", "silodem sweep")
    path = tmp_path / "one.toml"
    path.write_text(config_to_toml(load_config("paper-case2")))
    assert_names(refused(capsys, "sweep", str(path)), "is a scenario", "silodem run")


# --- files and folders ---------------------------------------------------------------------


def test_a_folder_given_as_the_config_file_is_refused(capsys, tmp_path):
    assert_names(refused(capsys, "run", str(tmp_path)), str(tmp_path), "is not a file")


def test_a_quoted_key_among_the_other_mistakes_is_named_as_toml_writes_it(capsys, tmp_path):
    """'silo."outlet.width"' (one name with a dot) was listed as silo.outlet.width, a path of
    three names that is not in the file."""
    text = config_to_toml(load_config("paper-case2"))
    text = text.replace("[material]\n", "[material]\nzz = 1\n", 1)
    text = text.replace("[silo]\n", '[silo]\n"outlet.width" = 1\n', 1)
    path = tmp_path / "quoted.toml"
    path.write_text(text)
    line = refused(capsys, "show", str(path))
    assert line.startswith("config error: unknown key 'material.zz'"), line
    assert_names(line, '(+1 more: silo."outlet.width" unknown)')


def test_a_folder_named_like_a_scenario_or_study_does_not_hide_it(tmp_path, monkeypatch):
    """`silodem run` makes runs/paper-case2; from inside runs/ that folder stood in the way of
    the scenario's name ('paper-case2 is not a file'). A folder is never a config, so the
    name is the embedded one's; a file of that name is still read first."""
    from silodem import scenario_files
    from silodem.study.spec import load_study

    monkeypatch.chdir(tmp_path)
    (tmp_path / "paper-case2").mkdir()
    (tmp_path / "paper-study").mkdir()
    embedded = Path(scenario_files.__file__).parent / "scenarios" / "paper-case2.toml"
    assert load_config("paper-case2") == load_config(str(embedded))
    assert load_study("paper-study").name == "paper-study"
    (tmp_path / "paper-case1").write_text(config_to_toml(load_config("paper-case2")))
    assert load_config("paper-case1").silo == load_config("paper-case2").silo


@pytest.mark.parametrize("name", ["", "   ", "x" * 5000])
def test_empty_or_impossible_scenario_names_are_refused(capsys, name):
    line = refused(capsys, "show", name)
    assert len(line) < 400
    assert_names(line, "paper-case2")


def test_out_pointing_at_a_file_is_refused(capsys, tmp_path):
    target = tmp_path / "results.txt"
    target.write_text("not a folder")
    assert_names(refused(capsys, "run", "--quick", "--out", str(target)), "--out", "is a file")
    below = target / "sub"
    assert_names(refused(capsys, "run", "--quick", "--out", str(below)), "--out",
                 "is a file, not a folder")


@pytest.mark.parametrize("points_to", ["gone/elsewhere", "link"])
def test_out_through_a_broken_symbolic_link_says_so(capsys, tmp_path, points_to):
    """An --out that is (or lies under) a symbolic link to nothing, or a link to itself, said
    "cannot write a folder there (File exists)", naming nothing that exists."""
    link = tmp_path / "link"
    link.symlink_to(points_to)
    for out in (link, link / "sub"):
        line = refused(capsys, "run", "--quick", "--out", str(out), silent=True)
        assert_names(line, f"--out {out}: {link} is a symbolic link to {points_to}",
                     "does not exist")


@pytest.mark.parametrize("command", [["run", "--quick"], ["validate", "--quick"],
                                     ["sweep", "paper-study", "--quick"]])
@pytest.mark.parametrize("where", ["/proc/silodem-out", "/sys/silodem-out", "name-too-long"])
def test_out_the_system_will_not_create_is_refused(capsys, tmp_path, command, where):
    """Folders the system refuses even to root (/proc, /sys; os.access says yes there) and a
    name longer than a file name may be: one line naming --out, before any work (a sweep
    announced its plan on stdout first)."""
    out = tmp_path / ("x" * 300) if where == "name-too-long" else Path(where)
    assert_names(refused(capsys, *command, "--out", str(out), silent=True), "--out",
                 "cannot write")
    # the folders above it that the refusal made are gone again (an empty runs/ was left)
    deep = tmp_path / "runs" / "of" / ("x" * 300)
    assert_names(refused(capsys, *command, "--out", str(deep), silent=True), "--out",
                 "cannot write")
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("command", [["plot"], ["animate"], ["run", "--resume"]])
def test_a_results_folder_name_the_system_refuses_is_one_line(capsys, tmp_path, command):
    assert_names(refused(capsys, *command, str(tmp_path / ("x" * 300))), "too long")


@pytest.mark.parametrize("sets, key", [
    (["measure.grid_cell=1e-5"], "measure.grid_cell"),
    (["measure.field_cell=1e-3"], "measure.field_cell"),
    (["measure.wall_bin=1e-7"], "measure.wall_bin"),
    (["measure.field_kernel=\"gaussian\"", "measure.field_cell=0.02", "measure.field_width=1.0"],
     "measure.field_width"),
    (["material.radius_min=2e-5", "material.radius_max=2e-5", "fill.band_height=0.5",
      "measure.grid_cell=0.1", "measure.field_cell=0.1", "measure.wall_bin=0.1"],
     "material.radius_max"),
])
def test_lengths_too_small_for_the_memory_are_refused_naming_the_key(capsys, tmp_path, sets,
                                                                       key):
    """Each value is valid, but the arrays it sizes would not fit (a 7e10-cell velocity grid,
    a 7e7-cell field grid, 1e8 wall bins, 5e9 search cells; a MemoryError traceback before),
    or a Gaussian kernel would be summed over 4e5 field cells per grain and contact."""
    args = [arg for item in sets for arg in ("--set", item)]
    line = refused(capsys, "run", "paper-case1", "--quick", "--out", str(tmp_path / "r"), *args)
    assert_names(line, key, "more than")


@pytest.mark.parametrize("key, limit", [("strip_width", "1.02 m"),
                                        ("coordination_band", "3.6 m"),
                                        ("switch_zone_half_height", "3.6 m")])
@pytest.mark.parametrize("value", ["3.61", "1e20", "1e300"])
def test_measurement_bands_larger_than_the_silo_are_refused(capsys, tmp_path, key, limit,
                                                             value):
    """paper-case1 --quick is 2.04 m x 3.6 m: a near-wall strip wider than half of it, or a
    band or zone taller than its walls, divides stresses by areas the silo does not have
    (a zone of 1e20 m made the report's figures fail with a singular matrix)."""
    line = refused(capsys, "run", "paper-case1", "--quick", "--out", str(tmp_path / "r"),
                   "--set", f"measure.{key}={value}")
    assert_names(line, f"measure.{key}", f"give at most {limit}")
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("sets", [["measure.wall_bin=10.0"], ["measure.grid_cell=1e300"],
                                  ["measure.field_cell=50.0"],
                                  ["measure.field_kernel=\"gaussian\"", "measure.field_width=1e300",
                                   "measure.field_cell=1e300"]])
def test_lengths_that_give_one_bin_are_accepted(sets):
    """A bin or cell larger than the silo is one bin over all of it (the grids clamp to at
    least one): a valid, coarse measurement; 1e300 m neither overflows nor is refused."""
    cfg = load_config("paper-case1", sets)
    assert check_numbers(cfg)[0] > 0


def test_a_gaussian_of_1e300_m_is_refused_without_overflow(capsys, tmp_path):
    """reach**2 of a 1e300 m kernel raised OverflowError (a traceback) in the size check."""
    line = refused(capsys, "run", "paper-case1", "--quick", "--out", str(tmp_path / "r"),
                   "--set", "measure.field_kernel=\"gaussian\"",
                   "--set", "measure.field_width=1e300")
    assert_names(line, "measure.field_width", "more than")

@pytest.mark.parametrize("speed", ["400.0", "1e300"])
def test_a_pouring_speed_that_jumps_a_radius_per_step_is_refused(capsys, tmp_path, speed):
    """paper-case2 --quick: dt = 2.38e-4 s and r_min = 0.09 m, so 378 m/s is the most; 1e300
    m/s ran until the guard stopped it and then overflowed in the energy bound (a traceback,
    no diagnostic.json, and a checkpoint that held the folder)."""
    line = refused(capsys, "run", "paper-case2", "--quick", "--out", str(tmp_path / "r"),
                   "--set", f"fill.initial_speed={speed}")
    assert_names(line, "fill.initial_speed", "more than its radius", "at most 378 m/s")
    assert not (tmp_path / "r").exists()

def test_a_loose_fill_that_cannot_fit_is_refused_before_the_run(capsys, tmp_path):
    """Refused before the run starts: no checkpoint is left, so the folder is not held by an
    'unfinished run' that cannot be resumed either."""
    line = refused(capsys, "run", "paper-case1", "--quick", "--out", str(tmp_path),
                   "--set", "fill.method=\"loose\"", "--set", "fill.n_particles=3000")
    assert_names(line, "fill.n_particles", "do not fit loose")
    assert not (tmp_path / "checkpoint.h5").exists()
    assert not (tmp_path / "results.h5").exists()


def test_values_that_make_no_run_are_refused_before_the_folder_is_made(capsys, tmp_path):
    out = tmp_path / "new"
    line = refused(capsys, "run", "--quick", "--out", str(out), "--set", "time.dt=1.0")
    assert_names(line, "time.dt", "stability limit")
    assert not out.exists()  # an empty folder was left behind before


def test_a_folder_in_the_way_of_a_file_is_named(capsys, tmp_path):
    """atomic_file names the file asked for, not its temporary name."""
    from silodem.atomic import write_atomic

    (tmp_path / "report.html").mkdir()
    with pytest.raises(IsADirectoryError, match="report.html"):
        write_atomic(tmp_path / "report.html", "x")
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]


def test_out_holding_an_unfinished_run_is_refused(capsys, tmp_path):
    (tmp_path / "checkpoint.h5").write_bytes(b"")
    line = refused(capsys, "run", "--quick", "--out", str(tmp_path))
    assert_names(line, "unfinished run", f"--resume {tmp_path}")


# --- --resume ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("extra", "flag"),
    [
        (["paper-case1"], "SCENARIO"),
        (["--set", "seed=3"], "--set"),
        (["--quick"], "--quick"),
        (["--out", "elsewhere"], "--out"),
    ],
)
def test_resume_with_a_config_or_out_is_refused(capsys, tmp_path, extra, flag):
    line = refused(capsys, "run", "--resume", str(tmp_path), *extra)
    assert_names(line, "--resume", flag)


def _foreign_h5(path: Path) -> None:
    with h5py.File(path, "w") as h5:
        h5.create_dataset("x", data=[1.0])


def _other_version(path: Path) -> None:
    with h5py.File(path, "w") as h5:
        h5.attrs["format"] = FORMAT
        h5.attrs["format_version"] = 99
        h5.attrs["silodem_version"] = "9.9"


def _finished(folder: Path) -> None:
    with h5py.File(folder / "results.h5", "w") as h5:
        h5.attrs["status"] = "complete"


@pytest.mark.parametrize(
    ("prepare", "needles"),
    [
        (None, ["does not exist"]),
        (lambda d: d.mkdir(), ["no checkpoint.h5"]),
        (lambda d: (d.mkdir(), (d / "checkpoint.h5").write_bytes(b"\0garbage" * 10)),
         ["cannot be read"]),
        (lambda d: (d.mkdir(), _foreign_h5(d / "checkpoint.h5")), ["not a silodem checkpoint"]),
        (lambda d: (d.mkdir(), _other_version(d / "checkpoint.h5")), ["format 99", "9.9"]),
        (lambda d: (d.mkdir(), _finished(d)), ["has finished"]),
        (lambda d: d.write_text("x"), ["is a file"]),
    ],
    ids=["missing", "empty", "garbage", "foreign", "other-version", "finished", "file"],
)
def test_resume_without_a_usable_checkpoint_is_refused(capsys, tmp_path, prepare, needles):
    folder = tmp_path / "run"
    if prepare is not None:
        prepare(folder)
    line = refused(capsys, "run", "--resume", str(folder), silent=True)  # no "resuming ..."
    assert_names(line, str(folder), *needles)


# --- fuzzing -------------------------------------------------------------------------------

_SCRATCH = tempfile.TemporaryDirectory(prefix="silodem-fuzz-")
_KEYS = [k.split(".") for k in schema_keys(Config)]
_JUNK = [["materal"], ["material", "knn"], ["silo", "kind", "x"], ["a", "b"], ["fill", ""]]

_scalars = st.one_of(
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.text(max_size=10),
    st.datetimes(timezones=st.just(dt.UTC)),
    st.dates(),
    st.times(),
)
_values = st.recursive(
    _scalars,
    lambda inner: st.lists(inner, max_size=3)
    | st.dictionaries(st.text(min_size=1, max_size=6), inner, max_size=3),
    max_leaves=6,
)
_edits = st.lists(
    st.tuples(st.sampled_from(_KEYS + _JUNK), st.none() | _values),  # None: delete the key
    max_size=4,
)


def _edited(data: dict, edits) -> dict:
    for path, value in edits:
        node = data
        for part in path[:-1]:
            child = node.get(part)
            if not isinstance(child, dict):
                child = node[part] = {}
            node = child
        if value is None:
            node.pop(path[-1], None)
        else:
            node[path[-1]] = value
    return data


def _loads_or_refuses(path: Path) -> None:
    try:
        cfg = load_config(str(path))
    except InputError as exc:
        assert str(exc) and "\n" not in str(exc)
    else:
        assert isinstance(cfg, Config)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenario=st.sampled_from(["paper-case1", "paper-case2"]), edits=_edits)
def test_fuzzed_toml_files_load_or_are_refused_in_one_line(scenario, edits):
    data = _edited(tomllib.loads(config_to_toml(load_config(scenario))), edits)
    path = Path(_SCRATCH.name) / "fuzz.toml"
    path.write_text(tomli_w.dumps(data), encoding="utf-8")
    _loads_or_refuses(path)


@settings(max_examples=100, deadline=None)
@given(content=st.binary(max_size=200) | st.text(max_size=200).map(str.encode))
def test_fuzzed_file_contents_load_or_are_refused_in_one_line(content):
    path = Path(_SCRATCH.name) / "raw.toml"
    path.write_bytes(content)
    _loads_or_refuses(path)


_extremes = st.sampled_from([5e-324, 1e-320, 1e-300, 1e-30, 1e-6, 0.5, 1.0, 89.99, 1e6, 1e30,
                             1e300, 1.7e308]) | st.floats(min_value=0, max_value=1e308)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenario=st.sampled_from(["paper-case1", "paper-case2", "paper-case2-hertz"]),
       sets=st.lists(st.tuples(st.sampled_from([
           "material.density", "material.radius_min", "material.radius_max",
           "material.thickness", "material.kn", "material.ks", "material.friction_deg",
           "material.restitution", "walls.kn", "walls.ks", "silo.cell_width",
           "silo.wall_height", "silo.outlet_width", "silo.hopper_angle_from_horizontal_deg",
           "fill.band_height", "fill.initial_speed", "time.dt", "time.safety", "gravity",
           "material.young_modulus", "material.poisson_ratio", "walls.young_modulus",
           "walls.poisson_ratio"]),
           _extremes | st.sampled_from([0.0, 0.25, 0.5])), max_size=3))
def test_extreme_numbers_build_a_run_or_are_refused_in_one_line(scenario, sets):
    """Either law: the paper's linear cases and a Hertz-Mindlin one (whose moduli are refused
    under the linear law, and the stiffnesses under Hertz-Mindlin, in one line too)."""
    items = [f"{key}={value!r}" for key, value in sets]
    try:
        cfg = load_config(scenario, items)
        check_numbers(cfg)
    except InputError as exc:
        assert "\n" not in str(exc)
        return
    run = SiloRun(cfg)
    assert math.isfinite(run.dt) and run.dt > 0


def test_a_wall_too_soft_to_limit_the_time_step_gives_the_grains_limit_without_a_warning():
    """A wall ratio m / k_wall beyond the largest float is inf, which the minimum passes over:
    dt_crit is then the grains' own limit, sqrt(min(f^2 m / k_n, m / (3 k_s))) with the series
    stiffnesses k/2 of two equal grains (Cundall & Strack 1979) and the dashpot's factor
    f = sqrt(1 + 4 zeta^2) - 2 zeta, zeta = -ln e / sqrt(pi^2 + ln^2 e) (docs/physics.md), and
    numpy says nothing."""
    cfg = load_config("paper-case1", ["material.density=1e250", "walls.kn=1e-90",
                                      "walls.ks=1e-90"])
    m = cfg.material
    m_min = m.density * math.pi * m.radius_min**2 * m.thickness
    zeta = -math.log(m.restitution) / math.sqrt(math.pi**2 + math.log(m.restitution) ** 2)
    f = math.sqrt(1.0 + 4.0 * zeta**2) - 2.0 * zeta
    expected = math.sqrt(min(f * f * m_min / m.kn, m_min / (3.0 * m.ks)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = SiloRun(cfg)  # (choose_time_step; check_numbers refuses the run, below)
    assert run.dt_crit == pytest.approx(expected, rel=1e-12)
    with pytest.raises(InputError, match="fell from the top of the walls"):
        check_numbers(cfg)  # dt ~ 1e120 s: a falling grain would cross the silo in a step


@pytest.mark.parametrize("scheme", ["tls", "ucx"])
def test_a_scheduler_address_dask_cannot_open_is_refused(capsys, tmp_path, scheme):
    """tls:// without certificates and ucx:// without UCX raise a TypeError in Dask's Client
    (a traceback before)."""
    line = refused(capsys, "sweep", "paper-study", "--quick", "--scheduler",
                   f"{scheme}://127.0.0.1:1", "--out", str(tmp_path / "s"))
    assert_names(line, "cannot reach the Dask scheduler", f"{scheme}://127.0.0.1:1")


@pytest.mark.parametrize("args", [["run", "--quick", "--out", ""], ["run", "--quick", "--out="],
                                  ["run", "--resume", " "], ["plot", ""],
                                  ["animate", "", "--format", "gif"],
                                  ["validate", "--quick", "-o", ""]])
def test_an_empty_path_is_refused_not_read_as_this_folder(capsys, tmp_path, monkeypatch, args):
    """click reads '' as '.': `--out ''` wrote a run into the working folder, and first
    removed the results, report and figures of any run already there."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "report.html").write_text("someone's report")
    line = refused(capsys, *args)
    assert_names(line, "an empty path")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]


def test_an_empty_option_value_after_the_folder_is_not_blamed_on_the_folder(capsys, tmp_path):
    line = refused(capsys, "animate", str(tmp_path), "--color", "")
    assert "DIR" not in line and "empty path" not in line


def test_a_set_value_holding_a_second_toml_line_is_not_split(capsys):
    """`--set $'material.kn=1e7\\nseed = 3'` set kn and dropped `seed = 3` without a word: the
    value is now taken whole, and the schema refuses it as a number."""
    line = refused(capsys, "show", "paper-case2", "--set", "material.kn=1e7\nseed = 3")
    assert_names(line, "material.kn", "valid number")


@pytest.mark.parametrize("value", ["0", "-2", "abc"])
def test_a_numba_thread_count_numba_cannot_use_is_refused(capsys, monkeypatch, value):
    """NUMBA_NUM_THREADS=0 ended in numba's ValueError traceback at the first parallel kernel."""
    monkeypatch.setenv("NUMBA_NUM_THREADS", value)
    line = refused(capsys, "run", "--quick", "--threads", "1")
    assert_names(line, "NUMBA_NUM_THREADS", repr(value))


@pytest.mark.parametrize("value", ["9" * 50, "9" * 5000, str(2**31), "\u00b2"])
def test_a_numba_thread_count_beyond_a_c_int_is_refused(capsys, monkeypatch, value):
    """NUMBA_NUM_THREADS of 5000 digits ended in Python's "Exceeds the limit (4300 digits)"
    ValueError, '²' (a digit to str.isdigit) in int()'s ValueError, and 50 nines ran until
    numba's C int wrapped to 0 threads ("Invalid number of threads ... a bug in Numba")."""
    monkeypatch.setenv("NUMBA_NUM_THREADS", value)
    line = refused(capsys, "run", "--quick", "--threads", "1")
    assert_names(line, "NUMBA_NUM_THREADS", str(2**31 - 1))  # the largest C int
    assert len(line) < 200, line


D4000 = "9" * 4000  # an integer Python writes, too long to quote
D5000 = "9" * 5000  # more digits than Python reads (sys.get_int_max_str_digits: 4300)


@pytest.mark.parametrize("args, name", [
    (["run", "--quick", "--threads", D4000], "--threads"),
    (["bench", "--n", D4000], "--n"),
    (["bench", "--n", "100", "--steps", D4000], "--steps"),
    (["bench", "--n", "100", "--rows", D4000], "--rows"),
    (["animate", "DIR", "--fps", D4000], "--fps"),
    (["sweep", "paper-study", "--quick", "--workers", D4000, "--out", "DIR/s"], "--workers"),
    (["show", "paper-case2", "--set", f"seed={D4000}"], "seed"),
    (["show", "paper-case2", "--set", f"fill.n_particles={D4000}"], "fill.n_particles"),
])
def test_an_integer_option_too_long_to_quote_is_named_by_its_digits(capsys, tmp_path, args,
                                                                    name):
    """A 4000-digit --n, --steps, --rows, --fps or --workers was quoted whole: a line of 4000
    characters."""
    line = refused(capsys, *(a.replace("DIR", str(tmp_path)) for a in args))
    assert_names(line, name, "an integer of 4000 digits")
    assert len(line) < 200, line


@pytest.mark.parametrize("args", [["run", "--quick", "--threads", D5000],
                                  ["bench", "--n", D5000], ["bench", "--steps", D5000],
                                  ["animate", "DIR", "--fps", D5000]])
def test_an_integer_option_beyond_pythons_digits_is_one_line(capsys, tmp_path, args):
    line = refused(capsys, *(a.replace("DIR", str(tmp_path)) for a in args))
    assert_names(line, args[-2], "integer")
    assert len(line) < 200, line


LONG = "x" * 5000  # a key 5,000 characters long: quoted cut to 60 (docs/reliability.md)


@pytest.mark.parametrize("item, needles", [
    (f"fill.{LONG}=1", [f"unknown key 'fill.{'x' * 52}...'", "allowed in [fill]: method"]),
    (f"{LONG}=1", [f"unknown key '{'x' * 57}...'", "allowed at the top level: name"]),
    (f"seed.{LONG}=1", ["'seed' is a value, not a section",
                        f"'seed.{'x' * 52}...' does not exist"]),
])
def test_a_long_unknown_set_key_is_quoted_cut_short(capsys, item, needles):
    """`--set fill.<5000 x>=1` echoed the key whole: a line of 5,000 characters."""
    line = refused(capsys, "show", "paper-case2", "--set", item)
    assert_names(line, *needles)
    assert len(line) < 300, line


def test_long_unknown_keys_in_a_file_are_quoted_cut_short(capsys, tmp_path):
    """Three 5,000-character unknown keys in a file made a line of 15,000 characters."""
    text = config_to_toml(load_config("paper-case2"))
    text = text.replace("[fill]\n", f"[fill]\n{LONG} = 1\n{LONG}y = 2\n", 1)
    path = tmp_path / "long.toml"
    path.write_text(f"{LONG}z = 3\n" + text)
    line = refused(capsys, "show", str(path))
    assert_names(line, "config error: unknown key '", "(+2 more: ", f"{'x' * 52}...")
    assert len(line) < 500, line


def test_a_long_unknown_key_in_a_study_is_quoted_cut_short(capsys, tmp_path):
    path = tmp_path / "study.toml"
    path.write_text(f'base = "paper-case2"\nseeds = [1]\n[grid]\n"fill.{LONG}" = [1, 2]\n')
    line = refused(capsys, "sweep", str(path), "--out", str(tmp_path / "s"))
    assert_names(line, f"unknown key 'fill.{'x' * 52}...'")
    assert len(line) < 300, line


@pytest.mark.parametrize("args", [["scenarios"], ["show", "paper-case2"], ["--version"],
                                  ["run", "--help"]])
def test_commands_that_compute_nothing_ignore_numbas_thread_count(args):
    """`NUMBA_NUM_THREADS=0 silodem scenarios` was refused although listing scenarios never
    imports numba (a fresh process: here numba is imported already)."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "0"}
    result = subprocess.run([sys.executable, "-m", "silodem", *args], capture_output=True,
                            text=True, env=env, check=False, timeout=120)
    assert result.returncode == 0 and result.stdout.strip(), result.stderr


@pytest.mark.parametrize("name", ["results.h5", "config.toml", "report.html"])
def test_animate_out_that_is_not_a_video_name_is_refused(capsys, tmp_path, name):
    """`silodem animate DIR --out DIR/results.h5` wrote an MP4 over the run's results (any
    suffix but .gif meant MP4): an --out that does not end in .mp4 or .gif is refused first."""
    (tmp_path / name).write_bytes(b"a run's file")
    line = refused(capsys, "animate", str(tmp_path), "--out", str(tmp_path / name))
    assert_names(line, "--out", f".{name.rsplit('.', 1)[1]}", ".mp4", ".gif")
    assert (tmp_path / name).read_bytes() == b"a run's file"


def test_a_scenario_name_with_spaces_around_it_says_so(capsys):
    """' paper-case2' said "unknown scenario 'paper-case2' (did you mean 'paper-case2'?)": the
    message hid the spaces that made the name unknown."""
    line = refused(capsys, "show", " paper-case2")
    assert_names(line, "' paper-case2'", "spaces", "did you mean 'paper-case2'?")


@pytest.mark.parametrize("command, name, hint", [("show", "PAPER-CASE2", "paper-case2"),
                                                 ("sweep", "Paper-Study", "paper-study")])
def test_a_scenario_or_study_name_in_the_wrong_case_gets_a_did_you_mean(capsys, command,
                                                                        name, hint):
    """'PAPER-CASE2' got no did-you-mean: difflib compares case, and no letter matched."""
    line = refused(capsys, command, name)
    assert_names(line, f"'{name}'", f"did you mean '{hint}'?")


def test_an_unknown_key_in_the_wrong_case_gets_a_did_you_mean(capsys):
    line = refused(capsys, "show", "paper-case2", "--set", "material.KN=3")
    assert_names(line, "'material.KN'", "did you mean 'material.kn'?")


@pytest.mark.parametrize("command, name", [("show", "my.yaml"), ("sweep", "grid.json")])
def test_a_missing_file_named_without_a_folder_is_called_a_missing_file(capsys, tmp_path,
                                                                        monkeypatch, command,
                                                                        name):
    """A missing 'my.yaml' (in the working folder) was an "unknown scenario 'my.yaml'", as
    if the user had mistyped a scenario's name; a name with a suffix is a file's name."""
    monkeypatch.chdir(tmp_path)
    line = refused(capsys, command, name)
    assert_names(line, "not found", name, ".toml")
    assert "unknown" not in line


def test_a_study_named_by_a_file_name_that_names_no_folder_is_refused(capsys, tmp_path):
    """A study without `name` is named by its file's stem: `..toml` gave the name '.', which
    the `name` key refuses, and the study went into studies/ itself, not studies/<name>."""
    study = tmp_path / "..toml"
    study.write_text('base = "paper-case2"\nseeds = [2]\n[grid]\n"fill.n_particles" = [100]\n')
    line = refused(capsys, "sweep", str(study), "--scheduler", "tcp://127.0.0.1:1")
    assert_names(line, "'.'", "cannot name a results folder", "name =")


def test_ctrl_c_while_the_command_line_is_imported_is_one_line_and_exit_130():
    """Ctrl-C in the part of a second that the import of silodem.cli takes, before its main
    can catch anything, printed a KeyboardInterrupt traceback; the script's launcher now ends
    it in one line and exit code 130, as an interrupt of a run does.  The interrupt is raised
    by an import hook at the import of silodem.cli, where a real Ctrl-C lands."""
    code = ("import sys\n"
            "class Interrupt:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name == 'silodem.cli':\n"
            "            raise KeyboardInterrupt\n"
            "sys.meta_path.insert(0, Interrupt())\n"
            "from silodem.launcher import main\n"
            "main()\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120, check=False)
    assert (result.returncode, result.stderr) == (130, "interrupted\n")


@pytest.mark.parametrize("args, code", [(["show", "paper-case2"], 0), (["scenarios"], 0),
                                        (["show", "no-such-scenario"], 2)])
def test_a_reader_gone_from_the_output_pipe_leaves_the_commands_own_exit_code(args, code):
    """`silodem ... | head -1`: once the reader had gone, click ended every command at once with
    exit code 1 and no word (a finished run and a validation whose checks all passed alike).
    With the pipe closed before the first line, the command ends with its own code, and
    nothing is printed on stderr but its own error."""
    proc = subprocess.Popen([sys.executable, "-m", "silodem", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == code, err
    assert err == ("" if code == 0 else err.splitlines()[0] + "\n")
    assert "Traceback" not in err and "BrokenPipe" not in err


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_while_the_script_exits_is_one_line(sig, code):
    """After its command ended, the interpreter's exit takes a good part of a second: a
    SIGINT or SIGTERM then killed the process without a word (exit -2 or -15).  The script
    answers it in one line, 130 or 143; its stdout up to then is kept.  The signal is sent
    from an atexit function, as the clean-up then runs."""
    code_text = ("import atexit, os, sys\n"
                 f"atexit.register(lambda: os.kill(os.getpid(), {int(sig)}))\n"
                 "sys.argv = ['silodem', 'scenarios']\n"
                 "from silodem.launcher import main\n"
                 "main()\n")
    result = subprocess.run([sys.executable, "-c", code_text], capture_output=True,
                            text=True, timeout=120, check=False)
    assert result.returncode == code, result.stderr
    assert "paper-case2" in result.stdout  # the command's own output
    assert result.stderr == (f"interrupted ({signal.Signals(sig).name}): as silodem exited, "
                             "after the command had ended (nothing it wrote is lost)\n")
    # after a command that failed (or was interrupted), its line and code stand alone
    failed = code_text.replace("'scenarios'", "'show', 'no-such-scenario'")
    result = subprocess.run([sys.executable, "-c", failed], capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert result.stderr.startswith("error: unknown scenario 'no-such-scenario'")



@pytest.fixture
def not_a_scheduler():
    """A TCP server on 127.0.0.1 that is not a Dask scheduler: 'http' answers every connection
    with an HTTP reply (a web server, the dashboard's port, a proxy), 'silent' accepts and
    never says anything.  Yields start(mode) -> address."""
    import socket
    import threading

    servers, held = [], []

    def start(mode: str) -> str:
        server = socket.create_server(("127.0.0.1", 0))
        servers.append(server)

        def serve():
            while True:
                try:
                    conn, _ = server.accept()
                except OSError:
                    return
                if mode == "http":
                    conn.sendall(b"HTTP/1.0 426 Upgrade Required\r\ncontent-length: 0\r\n\r\n")
                    conn.close()
                else:
                    held.append(conn)

        threading.Thread(target=serve, daemon=True).start()
        return f"tcp://127.0.0.1:{server.getsockname()[1]}"

    yield start
    for sock in servers + held:
        sock.close()


@pytest.mark.parametrize("mode", ["http", "silent"])
def test_an_address_that_is_no_dask_scheduler_is_refused_in_time(
        capsys, tmp_path, monkeypatch, not_a_scheduler, mode):
    """An HTTP server at the address ended in a traceback (Dask read its reply as a message
    length: a MemoryError for 3 EiB), and a server that accepts and never answers hung the
    sweep for ever (Dask's handshake read has no timeout, whatever Client's timeout says).
    The silent server is refused by the probe's own time limit (CONNECT_TIMEOUT_S, set to
    2 s here, which the line names); the HTTP server by its reply, before that limit."""
    from silodem.study import cluster as study_cluster

    monkeypatch.setattr(study_cluster, "CONNECT_TIMEOUT_S", 2.0)
    address = not_a_scheduler(mode)
    line = refused(capsys, "sweep", "paper-study", "--quick", "--scheduler", address,
                   "--out", str(tmp_path / "s"))
    assert_names(line, "cannot reach the Dask scheduler", address)
    assert ("(no Dask handshake within 2 s)" in line) == (mode == "silent")


def test_ctrl_c_while_the_scheduler_is_probed_ends_the_wait(monkeypatch, not_a_scheduler):
    """Ctrl-C while the probe waited on a silent server raised only after the probe's own
    timeout (its thread pool was joined on the way out): now the interrupt ends the wait
    at once, well before CONNECT_TIMEOUT_S."""
    import signal
    import threading
    import time

    from silodem.study import cluster as study_cluster

    monkeypatch.setattr(study_cluster, "CONNECT_TIMEOUT_S", 20.0)
    address = not_a_scheduler("silent")
    main_thread = threading.main_thread().ident
    ctrl_c = threading.Timer(0.5, signal.pthread_kill, (main_thread, signal.SIGINT))
    # Python's own Ctrl-C handler, which a shell's background job (SIGINT ignored) lacks
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    t0 = time.monotonic()
    ctrl_c.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            study_cluster._probe(address)
    finally:
        ctrl_c.cancel()  # never an interrupt in a later test
        signal.signal(signal.SIGINT, before)
    # not a speed bound: the interrupt must end the wait before the probe's own timeout
    # (the old code re-raised it only when the probe gave up, CONNECT_TIMEOUT_S later)
    assert time.monotonic() - t0 < study_cluster.CONNECT_TIMEOUT_S


def test_the_scheduler_probe_works_where_an_event_loop_runs(monkeypatch, not_a_scheduler):
    """A notebook's thread runs an event loop, where asyncio.run refuses to start: the probe
    of the address said 'asyncio.run() cannot be called from a running event loop' for every
    scheduler, a real one too.  From a running loop it must reach the server and time out
    on its silence as it does from a script."""
    import asyncio

    from silodem.errors import InputError
    from silodem.study import cluster as study_cluster

    monkeypatch.setattr(study_cluster, "CONNECT_TIMEOUT_S", 2.0)
    address = not_a_scheduler("silent")

    async def notebook_cell() -> str:
        with pytest.raises(InputError) as info:
            study_cluster.connect(address, None)
        return str(info.value)

    message = asyncio.run(notebook_cell())
    assert "cannot reach the Dask scheduler" in message
    assert "no Dask handshake within 2 s" in message


def test_waiting_for_workers_says_so_before_the_wait(monkeypatch):
    """--workers N on a scheduler with fewer workers waited up to WORKER_WAIT_S in silence; it
    now says what it waits for and how many have joined, then refuses in one line.  A
    scheduler of its own with no worker (an in-process LocalCluster with n_workers=0)."""
    from distributed import LocalCluster

    from silodem.errors import InputError
    from silodem.study import cluster as study_cluster

    monkeypatch.setattr(study_cluster, "WORKER_WAIT_S", 1.0)
    said: list[str] = []
    with (LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster,
          pytest.raises(InputError) as info):
        study_cluster.connect(cluster.scheduler_address, 2, said.append)
    assert said == [(f"waiting up to 1 s for 2 worker(s) at {cluster.scheduler_address} "
                     "(0 joined so far)")]
    assert "has 0 worker(s), fewer than 2 after 1 s" in str(info.value)


@pytest.mark.parametrize("sets, needles", [
    # 13 of 155 grains poured, then a warning at the end of the run (an audit)
    (["fill.max_time=1e-300"], ("fill.rate = 250 grains/s pours at most about 25 of the 155",
                                "fill.max_time = 1e-300 s")),
    (["fill.rate=1e-9"], ("fill.rate = 1e-09 grains/s pours at most", "fill.n_particles")),
    # measure/time empty, the circles' and profiles' tables of shape (0, ...)
    (["measure.interval=1000"], ("measure.interval = 1e+03 s is longer than the whole run",
                                 "fill.max_time + settle.max_time + discharge.max_time")),
    # the discharge window never reached; only the report said so
    (["measure.discharge_delay=100"], ("measure.discharge_delay = 100 s is not shorter",
                                       "than discharge.max_time = 10 s")),
    # report.html not written: 90 - 1e-300 rounded to 90 deg in the hopper theory
    (["silo.hopper_angle_from_horizontal_deg=1e-300"],
     ("silo.hopper_angle_from_horizontal_deg = 1e-300 deg cannot be told from a flat floor",
      "give silo.kind = 'flat'")),
    # every density and stress field value exactly 0
    (['measure.field_kernel="gaussian"', "measure.field_width=1e-6"],
     ("measure.field_width = 1e-06 m is less than half the field grid's largest cell side",
      "give at least 0.45 m")),
])
def test_values_whose_run_would_leave_its_work_undone_are_refused(capsys, tmp_path, sets,
                                                                   needles):
    """Each ran to exit 0 before (an audit) with an empty table, zero fields, a report not
    written or a pour stopped short; refused in one line before the folder is made."""
    out = tmp_path / "r"
    line = refused(capsys, "run", "paper-case2", "--quick", "--out", str(out),
                   *[arg for s in sets for arg in ("--set", s)])
    assert_names(line, *needles)
    assert not out.exists()


def test_the_field_width_bound_keeps_the_grids_gaussian_within_3_percent():
    """The sampled Gaussian's sum over a grid of cells dx x dz (times dx dz), brute force at
    the worst offsets of the grain to the grid, far from its edges: within 3 % of 1 at
    w = h/2 and 18 % off at 0.4 h (refused), as the refusal says. On paper-case2 --quick's own
    grid (0.8 m cells rounded to 0.68 x 0.90 m) the default width, half the larger side, is
    within 3 %; half the nominal 0.8 m (0.4 m, the former default) is 4 % off, and refused."""
    import numpy as np

    from silodem.measure.regions import field_width, grid_edges
    from silodem.scenario_files import quick_variant
    from silodem.silo.geometry import silo_shape

    def worst(w: float, dx: float = 1.0, dz: float = 1.0) -> float:
        errors = []
        for ox in np.linspace(0.0, 0.5, 6):
            for oz in np.linspace(0.0, 0.5, 6):
                x, z = np.meshgrid((np.arange(-20, 21) + ox) * dx, (np.arange(-20, 21) + oz) * dz)
                total = np.exp(-(x * x + z * z) / (2 * w * w)).sum() * dx * dz / (2 * np.pi * w * w)
                errors.append(abs(total - 1.0))
        return max(errors)

    assert worst(0.5) < 0.03 and 0.17 < worst(0.4) < 0.19
    quick = quick_variant(load_config("paper-case2", ['measure.field_kernel="gaussian"']))
    shape = silo_shape(quick)
    xe, ze = grid_edges(shape, 0.8)  # (field_cell unset: four mean diameters, 0.8 m)
    dx, dz = float(np.diff(xe).max()), float(np.diff(ze).max())
    assert (dx, dz) == (pytest.approx(0.68), pytest.approx(0.9))
    w = field_width(quick, shape)
    assert w == pytest.approx(0.45)
    assert worst(w, dx, dz) < 0.03 and 0.04 < worst(0.4, dx, dz) < 0.05
    check_numbers(quick)
    with pytest.raises(InputError, match="less than half the field grid's largest cell side"):
        check_numbers(quick.model_copy(update={"measure": quick.measure.model_copy(
            update={"field_width": 0.4})}))


def test_a_character_the_output_encoding_lacks_is_written_as_an_escape():
    """`show` prints the config's '§' (EN 1991-4 §5.3 in a description); an output encoding
    without it (PYTHONIOENCODING=ascii; not LC_ALL=C, where Python writes UTF-8 since 3.7)
    ended the command with a UnicodeEncodeError traceback.  It is written as an escape."""
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    result = subprocess.run([sys.executable, "-m", "silodem", "show", "paper-case2"],
                            capture_output=True, env=env, check=False, timeout=120)
    assert result.returncode == 0 and result.stderr == b"", result.stderr
    assert b"(\\xa75.3)" in result.stdout


def test_an_out_path_with_no_room_for_the_runs_files_is_refused_before_any_folder(tmp_path):
    """A --out of 4077 bytes made its 20 folders, then failed on its first file (an audit):
    the files a run writes in its folder add up to 48 bytes to its path (run.PATH_ROOM:
    figures/.fig7_switch_zone_evolution.png.tmp is 43), and a path must stay under the
    system's PATH_MAX (4096 on Linux, counting its NUL).  One byte short of room: refused,
    nothing made; with room: made."""
    from silodem.run import PATH_ROOM, check_out

    limit = os.pathconf(tmp_path, "PC_PATH_MAX")
    room = "figures/.fig7_switch_zone_evolution.png.tmp"
    assert len(room) <= PATH_ROOM

    def deep(size: int) -> Path:  # a path of ``size`` bytes under tmp_path/d
        left, names = size - len(os.fsencode(tmp_path / "d")), []
        while left > 256:  # ("/" and a name of 200)
            names.append("e" * 200)
            left -= 201
        path = tmp_path.joinpath("d", *names, "f" * (left - 1))
        assert len(os.fsencode(path)) == size
        return path

    with pytest.raises(InputError, match=f"a path of {limit - PATH_ROOM - 1} bytes leaves no "
                       f"room .* under the system's limit of {limit} bytes"):
        check_out(deep(limit - PATH_ROOM - 1))
    assert not (tmp_path / "d").exists()
    fits = deep(limit - PATH_ROOM - 2)
    check_out(fits)
    assert fits.is_dir()
    (fits / "figures").mkdir()
    (fits / room).write_bytes(b"")  # the run's longest name fits


def test_a_file_name_the_locale_cannot_decode_is_printed_as_its_bytes(tmp_path):
    """Under an ASCII locale with the C locale's coercion and UTF-8 mode off, Python holds the
    bytes of a UTF-8 name it cannot decode as surrogates; the error line wrote them as
    escapes ('Gr\\udcc3\\udcbc...'), a path that cannot be pasted back (an audit).  They go
    out as the bytes they were: the UTF-8 of the name on disk."""
    folder = tmp_path / "Grüße"
    folder.mkdir()
    missing = os.fsencode(folder) + "/nö such.toml".encode()
    env = {**os.environ, "LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    env.pop("LANG", None)
    env.pop("PYTHONIOENCODING", None)
    result = subprocess.run([sys.executable, "-m", "silodem", "run", missing],
                            capture_output=True, env=env, check=False, timeout=120)
    assert result.returncode == 2
    assert result.stderr.startswith(b"error: file not found: " + missing + b" "), result.stderr
    assert b"\\udc" not in result.stderr


@pytest.mark.parametrize("blank", ["", " "])
def test_a_blank_numba_thread_count_is_unset(blank):
    """`NUMBA_NUM_THREADS= silodem show` (blank: unset, as silodem reads it) printed numba's
    parse warning with a ValueError traceback at numba's import."""
    env = {**os.environ, "NUMBA_NUM_THREADS": blank}
    result = subprocess.run([sys.executable, "-m", "silodem", "show", "paper-case2"],
                            capture_output=True, text=True, env=env, check=False, timeout=120)
    assert result.returncode == 0 and result.stderr == "", result.stderr


def test_a_terminal_escape_in_the_input_is_shown_not_sent(capsys):
    """`--set $'material.kn=\\x1b[2J'`: the error line carried the live ESC of the value it
    quoted after '(from --set ...)', which clears a terminal's screen; newlines were already
    made spaces.  Control characters are written as escapes."""
    line = refused(capsys, "show", "paper-case2", "--set", "material.kn=\x1b[2J")
    assert not any(ord(c) < 32 or 127 <= ord(c) < 160 for c in line), repr(line)
    assert line.endswith("(from --set material.kn=\\x1b[2J)"), line


def test_quick_says_whose_numbers_its_check_failures_give(capsys, tmp_path):
    """10 million grains under --quick: "pours at most about 3.78e+03 of the 3600000 grains
    ... in fill.max_time = 15 s", numbers of the shrunk config that no file holds (0.36 of
    the grains, the fill capped at 15 s), without a word of --quick.  The line says they are
    the quick variant's (its bounds are the ones the run asked for must meet); where only
    the quick variant fails, it is --quick that cannot shrink the case."""
    text = config_to_toml(load_config("paper-case2"))
    text, count = re.subn(r"^n_particles = \d+", "n_particles = 10000000", text,
                          flags=re.MULTILINE)
    assert count == 1
    path = tmp_path / "big.toml"
    path.write_text(text, encoding="utf-8")
    line = refused(capsys, "run", str(path), "--quick", "--out", str(tmp_path / "r"))
    assert_names(line, "fill.rate = 250 grains/s", "of the 3600000 grains",
                 "fill.max_time = 15 s", "values of the --quick variant",
                 f"'silodem show {path} --quick' prints them")
    # 430 grains at 10 grains/s fill in 43 s of 60; the quick 155 need 15.5 s of the 15 s cap
    line = refused(capsys, "run", "paper-case2", "--quick", "--set", "fill.rate=10", "--set",
                   "fill.max_time=60", "--out", str(tmp_path / "r"))
    assert_names(line, "--quick cannot shrink 'paper-case2': fill.rate = 10 grains/s",
                 "of the 155 grains", "fill.max_time = 15 s")
