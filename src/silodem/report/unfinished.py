"""What the report says of a run that had not ended when its results.h5 was written.

results.h5 is rewritten at every checkpoint and when a run is stopped (silodem.output.
write_results): its attributes ``status`` ("complete", "running", "interrupted",
"unstable"), ``phase`` and ``time`` say how far it goes.  ``silodem plot`` draws such a
file as it draws a finished run's; :func:`banner_html` is the box at the top of its
report.html, :func:`note_line` the line ``silodem plot`` prints on stderr.
"""

from __future__ import annotations

import html
from pathlib import Path

from silodem.checkpoint import CHECKPOINT_NAME as CHECKPOINT
from silodem.report.analysis import UNSETTLED, Analysis, stopped_at

DIAGNOSTIC = "diagnostic.json"  # silodem.run_folder.DIAGNOSTIC_NAME: why an unstable run stopped

# how the run had stopped, by status: for the banner, and shorter for the stderr line
_HOW = {
    "interrupted": ("it was interrupted (SIGINT or SIGTERM)", "interrupted"),
    "running": ("it was saved at a checkpoint while the run went on,", "saved while running"),
    "unstable": ("it was stopped as unstable", "stopped as unstable"),
}


def _how(status: str) -> tuple[str, str]:
    return _HOW.get(status, (f"its status is '{status}'", f"status {status}"))


def resume_command(folder: Path) -> str | None:
    """'silodem run --resume DIR' when ``folder`` holds a checkpoint.h5 to go on from."""
    return f"silodem run --resume {folder}" if (folder / CHECKPOINT).is_file() else None


def note_line(a: Analysis, folder: Path | str) -> str | None:
    """The one line ``silodem plot`` prints on stderr for an unfinished run (None for a
    finished one); ``folder`` as the user gave it."""
    if not a.unfinished:
        return None
    folder = Path(folder)
    status = str(a.res.attrs.get("status"))
    command = resume_command(folder)
    if command and status == "unstable":  # (its checkpoint is the last good state)
        then = (f"'{command}' only repeats it to the same failure; mend the config and start "
                "it again")
    else:
        then = (f"continue it with '{command}'" if command else
                f"{folder} holds no {CHECKPOINT} to continue it from")
    return (f"silodem: {folder} holds an unfinished run ({_how(status)[1]} "
            f"{stopped_at(a.res)}): its report covers what was reached; {then}")


def _reached(a: Analysis) -> str:
    """What the phase the run stopped in means for the report's windows."""
    phase = str(a.res.attrs.get("phase", ""))
    if phase == "fill":
        return ("It stopped while filling: there is no settled fill and no discharge, and the "
                "figures and numbers show the filling reached.")
    if phase == "settle" or (phase != "discharge" and not a.settled):
        return ("Settling had not ended: there is no settled snapshot (no free surface, bulk "
                "density or Janssen fit), what a finished run measures after filling is here "
                f"measured {UNSETTLED}, the last measure.window of the settling reached, and "
                "nothing of the discharge was reached.")
    if phase == "discharge":
        t = a.res.attrs.get("time")
        t0 = a.res.events.get("discharge_start_time")
        since = (f", {float(t) - float(t0):.3g} s after the gate opened"
                 if isinstance(t, int | float) and isinstance(t0, int | float) else "")
        return (f"It stopped during the discharge{since}: the numbers after filling are the "
                "settled fill's, while those during discharge (the discharge window, rate, "
                "flow pattern, dead zones, the force networks late in the discharge) cover "
                "only the part of the discharge reached.")
    return ""


def banner_html(a: Analysis) -> str:
    """The box at the top of report.html for an unfinished run ("" for a finished one)."""
    if not a.unfinished:
        return ""
    res = a.res
    status = str(res.attrs.get("status"))
    steps = res.attrs.get("steps")
    step = f" (step {steps})" if isinstance(steps, int) else ""
    folder = res.folder.resolve()
    text = [(f"Unfinished run: this results.h5 was written before the run ended: "
             f"{_how(status)[0]} {stopped_at(res)}{step}. Measurements labelled after "
             "filling or during discharge cover only what the run reached.")]
    if status == "running":
        text.append("The run may still be going, or was killed.")
    reached = _reached(a)
    if reached:
        text.append(reached)
    if status == "unstable" and (res.folder / DIAGNOSTIC).is_file():
        text.append(f"{folder / DIAGNOSTIC} says what went wrong.")
    command = resume_command(folder)
    if command and status == "unstable":  # the checkpoint: the last good state, its config
        text.append(f"{command} only repeats it to the same failure (the checkpoint keeps the "
                    "run's config): mend the config and start the run again.")
    elif command:
        when = "Once it no longer runs, continue" if status == "running" else "Continue"
        text.append(f"{when} it with: {command}")
    else:
        text.append(f"The folder holds no {CHECKPOINT} to continue it from.")
    body = " ".join(html.escape(t) for t in text)
    return f"<p class='unfinished' id='unfinished'>{body}</p>"
