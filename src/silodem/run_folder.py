"""The run folder's files: the names a run writes into its folder, and what a new run in the
folder of an earlier one replaces (docs/reliability.md, "A new run in a used folder").

:func:`clear_previous_run` removes the earlier run's results, pictures, report and diagnosis
(an unstable run's checkpoint.h5 too, :func:`ended_unstable`), and refuses, removing nothing,
files of those names that no silodem run wrote (:func:`check_replaceable`);
:func:`replacing_note` says what a new run replaces; :func:`remove_partial_saves` removes the
temporary files of saves that a SIGKILL cut short; :func:`folder_lock` keeps a second run (a
resume of the same folder, say) out of a folder while a run writes there."""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from silodem.checkpoint import CHECKPOINT_NAME, FAILURE_NAME
from silodem.errors import InputError
from silodem.silo import frame_store
from silodem.silo.frames import FOLDER

DIAGNOSTIC_NAME = "diagnostic.json"
RESULTS_NAME = "results.h5"

# what a run and its pictures write into the folder (the VTK writer clears its own files)
ANIMATIONS = ("animation.mp4", "animation.gif")  # silodem animate's default names
PICTURES = ("report.html", "settled.png", "final.png", *ANIMATIONS)  # (and figures/*.png)
_RUN_FILES = (RESULTS_NAME, *PICTURES, DIAGNOSTIC_NAME, FAILURE_NAME)


# the second line of the config.toml a run writes, which tells it from a copy of
# 'silodem show' (the same first line) that a user saved there (check_config_kept)
RUN_CONFIG_MARK = "# The config of the run in this folder: a new run here replaces this file."


def run_config_text(toml_text: str) -> str:
    """The config.toml a run writes: ``toml_text`` (``config_to_toml``'s) with
    ``RUN_CONFIG_MARK`` as its second line."""
    head, _, rest = toml_text.partition("\n")
    return f"{head}\n{RUN_CONFIG_MARK}\n{rest}"


def _replaced_files(out: Path) -> list[Path]:
    """The files of ``out`` that ``clear_previous_run`` removes by name (not the frames' and
    VTK writers' own files, which they recognise); an unstable run's checkpoint.h5 among them
    (``ended_unstable``)."""
    found = [out / name for name in _RUN_FILES if (out / name).exists()] + _figures(out)
    if (out / CHECKPOINT_NAME).exists() and ended_unstable(out):
        found.append(out / CHECKPOINT_NAME)
    return found


def ended_unstable(out: Path) -> bool:
    """Whether the last run in ``out`` was stopped as unstable: its results.h5, written by
    silodem, has ``status = "unstable"`` (a resume of it, or a new run, rewrites that file at
    its first save).  The checkpoint.h5 such a run leaves is the last good state before the
    failure, with the failing config: a resume is bit-identical and comes to the same failure,
    so a new run there (the config mended) replaces it with the run's other files, instead of
    being refused as over an unfinished run."""
    attrs = _silodem_attrs(out / RESULTS_NAME)
    status = attrs.get("status") if attrs is not None else None
    if isinstance(status, bytes):
        status = status.decode(errors="replace")
    return status == "unstable"


def _silodem_attrs(results: Path) -> dict[str, Any] | None:
    """The root attributes of ``results`` when silodem wrote it (it has ``silodem_version``);
    None for another file, or one that cannot be read."""
    import h5py

    try:
        with h5py.File(results, "r") as h5:
            return dict(h5.attrs) if "silodem_version" in h5.attrs else None
    except (OSError, ValueError):
        return None


def _written_by_silodem(results: Path) -> bool:
    return _silodem_attrs(results) is not None


def _a_runs_record(out: Path) -> bool:
    """Whether ``out`` holds a file only a silodem run writes: its results.h5 or failure.h5
    (attribute ``silodem_version``), or its diagnostic.json (key ``silodem_version``).  An
    unstable run stopped by a second signal, or whose results.h5 could not be written, leaves
    the last two without the first."""
    import json

    if _written_by_silodem(out / RESULTS_NAME) or _written_by_silodem(out / FAILURE_NAME):
        return True
    try:
        diagnosis = json.loads((out / DIAGNOSTIC_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(diagnosis, dict) and "silodem_version" in diagnosis


def foreign_files(out: Path, found: list[str], writer: str, why: str, flag: str) -> InputError:
    """The refusal of a folder ``out`` whose files ``found`` (names relative to it) a new
    ``writer`` ("run", "study") there would replace, though ``why`` says it did not write
    them: one line naming the first of them and how many more."""
    more = f" (+{len(found) - 1} more)" if len(found) > 1 else ""
    return InputError(f"{flag} {out} holds {found[0]}{more}, which a {writer} there would "
                      f"replace, but {why}; give a new or empty folder, or move those files")


def check_replaceable(out: Path, flag: str = "out") -> bool:
    """Whether ``out`` holds an earlier run's files, which a new run there replaces; InputError
    if it holds files of those names that no silodem run wrote (no config.toml and a run's
    own record, :func:`_a_runs_record`, beside them): a user's own results.h5 or figures/*.png
    in a folder given as ``--out`` were deleted without a word, and so were a report.html and
    figures beside a config.toml of the user's own, with no results.h5.  A study's folder
    (study.toml: 'silodem sweep --out' made it) is refused whatever it holds: its runs have
    folders of their own, under runs/."""
    if (out / "study.toml").is_file():
        raise InputError(f"{flag} {out} is a study's folder (study.toml): a run there would mix "
                         "its files with the study's; give another folder")
    found = _replaced_files(out)
    if not found:
        return False
    has_config = (out / "config.toml").is_file()
    if not (has_config and _a_runs_record(out)):
        why = ("no silodem run wrote it (no config.toml and silodem results.h5 there)"
               if not has_config else "no silodem run wrote it (a config.toml, but no "
               "results.h5 that silodem wrote, or one too damaged to read)")
        raise foreign_files(out, [str(f.relative_to(out)) for f in found], "run", why, flag)
    return True


def check_config_kept(source: str | None, out: Path, cfg: Any, flag: str = "--out") -> None:
    """InputError when the run would replace ``out``'s config.toml, not an earlier run's
    (beside its results, :func:`_a_runs_record`), with something else:

    * the very file given (``source``, as the command line took it; None from the API), when
      it is not written by silodem (no ``config_to_toml`` header: its comments and layout
      would go) or its values differ from the run's config ``cfg`` (``--set``, ``--quick``):
      a run rewrote the file it was given without a word;
    * another config.toml that no run wrote: a user's own file in the folder given as
      ``--out`` was written over without a word, also a copy of ``silodem show``'s output (the
      README's way to write a config; the same header) with values of the user's.

    A config a run wrote there, run again as it is, passes, also one written by another
    version (its comments' words may differ); so does one a run stopped before its first save
    wrote (its ``RUN_CONFIG_MARK``: a run interrupted while its kernels compiled, run again
    with other values), and a copy with the run's own values (nothing is lost)."""
    from silodem.scenario_files import CONFIG_HEADER

    target = out / "config.toml"
    try:
        if not target.is_file():
            return
        given = source is not None and Path(source).is_file() and Path(source).samefile(target)
        if not given and _a_runs_record(out):  # an earlier run's: replaced with its results
            return
        text = target.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError, ValueError):
        return
    ours = text.startswith(CONFIG_HEADER)
    if not given:
        if not ours:
            raise InputError(f"{flag} {out} holds a config.toml that silodem did not write (no "
                             f"'{CONFIG_HEADER.strip()}' line at its top) and no run's results, "
                             "which the run would write over; give a new or empty folder, or "
                             "move that file")
        if text.split("\n")[1:2] != [RUN_CONFIG_MARK] and not _same_values(target, cfg):
            raise InputError(f"{flag} {out} holds a config.toml that no run wrote (a copy of "
                             "'silodem show'?) with other values than this run's, and no run's "
                             "results; the run would write over it; give a new or empty folder, "
                             "or move that file")
        return
    if not (ours and _same_values(target, cfg)):
        raise InputError(f"{flag} {out}: the config given, {source}, is that folder's "
                         "config.toml, which the run replaces with its resolved config; copy "
                         "it and run the copy, or give another --out")


def _same_values(path: Path, cfg: Any) -> bool:
    """Whether the config file ``path`` holds the values of ``cfg`` (False when it cannot be
    read as a config)."""
    from silodem.scenario_files import load_config

    try:
        return load_config(str(path)).model_dump() == cfg.model_dump()
    except InputError:
        return False


def replacing_note(out: Path, flag: str = "out") -> str | None:
    """What a new run in ``out`` replaces, in the words of the command line's note (printed on
    stderr) and of the API's warning; None when there is nothing to replace.  InputError as
    :func:`check_replaceable` for files no silodem run wrote."""
    unstable = ended_unstable(out)  # (read before anything is replaced)
    if not check_replaceable(out, flag):
        return None
    if unstable:
        return (f"replacing the earlier unstable run in {out}, its checkpoint.h5 included (a "
                "resume of it only comes to the same failure)")
    return f"replacing the earlier run's results in {out}"


def clear_previous_run(out: Path) -> None:
    """Remove from ``out`` the files an earlier run wrote there (results.h5, its pictures and
    report, a failed run's diagnosis and failure state, an unstable run's checkpoint.h5
    (``ended_unstable``); only these names, ``figures/*.png``, the frames'
    segment files in ``frames/`` and the VTK writer's own files in ``vtk/``), so that a
    fresh run's folder never shows the old run's results beside the new config, even if the
    new run is stopped before its first save or writes no VTK files.  InputError, removing
    nothing, where those files are not a silodem run's (``check_replaceable``)."""
    from silodem.viz.vtk import remove_written

    check_replaceable(out)
    for path in _replaced_files(out):
        path.unlink(missing_ok=True)
    remove_partial_saves(out)
    frame_store.clear(out / FOLDER)
    remove_written(out / "vtk")


def remove_pictures(out: Path) -> None:
    """Remove the pictures of an interrupted run drawn so far (``silodem plot`` and
    ``animate`` on it: report.html, settled.png, final.png, figures/*.png, the animations
    under their default names), before a resume: they stayed beside the finished run's
    results, the report's banner still saying "Unfinished run ... continue it with ..." when
    the run drew no report of its own (``measure.report = false``)."""
    for path in [out / name for name in PICTURES] + _figures(out):
        path.unlink(missing_ok=True)


def _figures(out: Path) -> list[Path]:
    """The report's figures/*.png in ``out``, sorted."""
    figures = out / "figures"
    return sorted(figures.glob("*.png")) if figures.is_dir() else []


def remove_partial_saves(out: Path) -> None:
    """Remove the temporary files (``atomic.atomic_file``'s ``.NAME.tmp``) of results.h5,
    checkpoint.h5, config.toml and the run's other files (``_RUN_FILES``: pictures, report,
    an unstable run's failure.h5 and diagnostic.json) that a SIGKILL in the middle of a save
    left in ``out``: the next save of the same file replaced them, but a run that saved no
    more (it ended, or checkpoints are off) kept a stale copy of a checkpoint beside its
    results, and a failure save cut short left its partial failure.h5."""
    for name in (*_RUN_FILES, CHECKPOINT_NAME, "config.toml"):
        (out / f".{name}.tmp").unlink(missing_ok=True)


@contextlib.contextmanager
def folder_lock(out: Path) -> Iterator[None]:
    """Hold an exclusive ``flock`` on the folder ``out`` itself while the block runs;
    InputError, at once, when another process holds it.  A ``silodem run --resume DIR``
    started while the run in DIR was still going ran beside it: both exited 0, and
    results.h5 named frame segment files that one of them had removed.  The lock goes with
    the process (the kernel releases it however the process ends), and leaves no file."""
    fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(f"{out} is in use by another silodem run; wait for it to end, "
                             "or give another folder") from None
        yield
    finally:
        os.close(fd)  # (releases the lock)


def check_not_in_use(out: Path) -> None:
    """InputError when another process holds ``out``'s lock (:func:`folder_lock`), so that
    the command line refuses before it says anything of the run; nothing when ``out`` is no
    folder yet.  (The run takes the lock itself when it starts.)"""
    try:
        if not Path(out).is_dir():
            return
        with folder_lock(Path(out)):
            pass
    except OSError:  # a path the system refuses (too long, ...): the output checks say so
        return
