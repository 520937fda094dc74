"""Pictures of the force network at chosen moments of a run, as PNG bytes (for the report).

``which`` names a moment:

* ``"end-of-filling"`` (or ``"settled"``): the last frame before the gate opened;
* ``"early-discharge"``: the frame nearest to 15 % of the discharge duration after the gate
  opened;
* ``"late-discharge"``: the frame nearest to 75 % of the discharge duration (either moment:
  none when that frame is more than ``NEAR_SHARE`` of the duration away from it, as with an
  ``output.frame_interval`` as long as the discharge);
* ``"final"``: the last frame;
* a number: the frame nearest to that time [s].
"""

from __future__ import annotations

import math
import numbers
from pathlib import Path

from silodem.silo.frames import Frame, Frames

VIEWS = ("end-of-filling", "early-discharge", "late-discharge")
_DISCHARGE_FRACTION = {"early-discharge": 0.15, "late-discharge": 0.75}
# a discharge moment's frame lies within this share of the discharge's duration of it: half
# the span between the two moments (with frames 1000 s apart the "early discharge" picture
# was the run's last frame, at 100 % of it: an audit)
NEAR_SHARE = 0.3


def select_frame(frames: Frames, which: str | float) -> Frame:
    """The frame of ``frames`` named by ``which`` (see the module); ValueError if none."""
    if len(frames) == 0:
        raise ValueError("the run has no frames")
    if not isinstance(which, str):
        if isinstance(which, bool) or not isinstance(which, numbers.Real) \
                or not math.isfinite(which):
            raise ValueError(f"the moment must be one of {', '.join(VIEWS)}, 'final', "
                             f"'settled' or a time in seconds; got {which!r}")
        return frames.nearest(float(which))
    if which in ("end-of-filling", "settled"):
        return frames.end_of_filling()
    if which == "final":
        return frames[-1]
    if which in _DISCHARGE_FRACTION:
        out = [k for k, phase in enumerate(frames.phases) if phase == "discharge"]
        if not out:
            raise ValueError(f"no '{which}' picture: the run has no discharge frames")
        times = frames.times
        t0 = float(frames.events.get("discharge_start_time", times[out[0]]))
        duration = float(frames.events.get("discharge_time", times[out[-1]] - t0))
        target = t0 + _DISCHARGE_FRACTION[which] * duration
        k = min(out, key=lambda j: abs(times[j] - target))
        if duration > 0 and abs(times[k] - target) > NEAR_SHARE * duration:
            raise ValueError(f"no '{which}' picture: the saved frame nearest to "
                             f"{100 * _DISCHARGE_FRACTION[which]:.0f} % of the discharge time "
                             f"is at {100 * (times[k] - t0) / duration:.0f} % of it "
                             "(output.frame_interval too long for the discharge)")
        return frames[k]
    raise ValueError(f"unknown moment {which!r}: use one of {', '.join(VIEWS)}, 'final', "
                     "'settled' or a time in seconds")


_LABEL = {"end-of-filling": "end of filling (settled)", "early-discharge": "early discharge",
          "late-discharge": "late discharge", "final": "end of run",
          "settled": "end of filling (settled)"}


def force_network_png(results_h5: Path | str | Frames, which: str | float = "end-of-filling",
                      *, color: str = "none", height_px: int = 700) -> bytes:
    """PNG bytes of the grains and the force network (line width ~ normal force) of one moment
    of a run (``which``, see the module), from its results.h5 or its results folder (or
    already read ``Frames``).  ValueError (one line) for a file without frames, a moment the
    run does not have, or a bad ``color`` or ``height_px``.

    ``color``: "none" (plain grains, the default), "velocity", "force" or "coordination"."""
    from silodem.viz.draw import FrameArtist

    frames = _frames(results_h5)
    frame = select_frame(frames, which)
    artist = FrameArtist(frames, color, height_px=height_px, titles=_layout_titles(frames))
    return _png(artist, frame, which, frames)


def _frames(results_h5: Path | str | Frames) -> Frames:
    """The frames of a run's results.h5, of its results folder, or ``results_h5`` itself;
    ValueError (one line) when there are none to read."""
    from silodem.errors import InputError
    from silodem.viz.animate import read_run_frames

    if isinstance(results_h5, Frames):
        return results_h5
    if not isinstance(results_h5, str | Path):
        raise TypeError(f"results_h5 must be a run's results.h5 or its results folder (or "
                         f"Frames); got a {type(results_h5).__name__}")
    path = Path(results_h5)
    try:
        return read_run_frames(path / "results.h5" if path.is_dir() else path)
    except InputError as exc:
        raise ValueError(str(exc)) from None


_UNSETTLED = "last frame saved, not settled (unfinished run)"


def _title(label: str, time: float, n: int) -> str:
    return f"{label + ', ' if label else ''}t = {time:.2f} s ({n} grains)"


def _layout_titles(frames: Frames) -> list[str]:
    """The longest titles a picture of ``frames`` may have (the label of each moment the run
    has, with its last time and most grains): the figure keeps room for them, the same for
    every moment, so that a picture is the same drawn alone or with the others."""
    from silodem.viz.scales import most_grains

    time, n = float(frames.times.max()), most_grains(frames)
    labels = {_UNSETTLED if v in ("end-of-filling", "settled") and not frames.settled else label
              for v, label in _LABEL.items()}
    return [_title(label, time, n) for label in sorted(labels)]


def _png(artist, frame: Frame, which: str | float, frames: Frames) -> bytes:
    """PNG bytes of ``frame`` drawn by ``artist``, titled with the moment ``which`` (of
    ``frames``: the "end of filling" of a run stopped before settling ended is its last
    frame, and says so)."""
    label = _LABEL.get(which, "") if isinstance(which, str) else ""
    if which in ("end-of-filling", "settled") and not frames.settled:
        label = _UNSETTLED
    artist.draw(frame, title=_title(label, frame.time, frame.n))
    return artist.png()


def force_network_pngs(results_h5: Path | str | Frames) -> dict[str, bytes]:
    """The PNGs of ``VIEWS`` that the run has (no discharge pictures without a discharge;
    no late one when it would be the early one's frame: a discharge of one saved frame),
    drawn by one artist (one pass over the frames for its scales), as ``force_network_png``
    draws each.  ValueError (one line) when the file has no frames."""
    from silodem.viz.draw import FrameArtist

    frames = _frames(results_h5)
    if len(frames) == 0:  # (as force_network_png says; the report takes it as no pictures)
        raise ValueError("the run has no frames")
    artist = FrameArtist(frames, "none", height_px=700, titles=_layout_titles(frames))
    out, drawn = {}, set()
    for view in VIEWS:
        try:
            frame = select_frame(frames, view)
        except ValueError:
            continue
        if frame.step in drawn:  # (frames read from a file are new objects each time)
            continue
        drawn.add(frame.step)
        out[view] = _png(artist, frame, view, frames)
    return out
