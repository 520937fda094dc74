"""``silodem animate``: an MP4 or GIF of a run's filling and discharge from its saved frames.

Every frame of results.h5 ``/frames`` becomes one picture (``FrameArtist``): disks to scale,
coloured by speed, contact force or coordination number, with the force chains drawn.  MP4 is
encoded by FFmpeg through imageio (the binary comes with the imageio-ffmpeg package); GIF is
written by Pillow.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from silodem.atomic import atomic_file
from silodem.checkpoint import CHECKPOINT_NAME as CHECKPOINT
from silodem.errors import InputError, short_repr
from silodem.silo.frames import Frames, NoFramesError, read_frames

FORMATS = ("mp4", "gif")
ANIMATION_COLORS = ("velocity", "force", "coordination")
_GIF_HEIGHT = 560  # px: GIFs get large quickly
_MP4_HEIGHT = 800  # px


@dataclass
class AnimationResult:
    path: Path
    frames: int
    seconds: float  # wall time spent rendering and encoding [s]
    width: int
    height: int
    fps: float  # frames per second the file plays at (a GIF's: 100 / its delay in 1/100 s)


def load_run_frames(run_dir: Path | str) -> Frames:
    """The frames of the results folder ``run_dir``; an InputError (one line) when there are
    none to read."""
    d = Path(run_dir)
    if not d.exists():
        raise InputError(f"results folder '{d}' does not exist")
    if not d.is_dir():
        raise InputError(f"'{d}' is not a folder; give the results folder of a run "
                         "(silodem run ... --out DIR)")
    h5 = d / "results.h5"
    if not h5.is_file():
        if (d / CHECKPOINT).is_file():  # ('silodem run --out' refuses the folder of such a run)
            raise InputError(f"'{d}' has no results.h5 but the {CHECKPOINT} of an unfinished "
                             f"run: continue it with 'silodem run --resume {d}' (it writes "
                             "results.h5 as it goes)")
        raise InputError(f"'{d}' has no results.h5; make one with: silodem run ... --out {d}")
    frames = read_run_frames(h5)
    if len(frames) == 0:
        raise InputError(f"'{h5}' holds no frames: the run was shorter than "
                         "output.frame_interval")
    return frames


def read_run_frames(h5: Path) -> Frames:
    """The frames of the results file ``h5``; an InputError (one line) when it cannot be read
    or has no /frames."""
    if not h5.is_file():
        raise InputError(f"'{h5}' does not exist" if not h5.exists() else
                         f"'{h5}' is not a file; give a run's results.h5 or its folder")
    try:
        return read_frames(h5)
    except NoFramesError as exc:
        raise InputError(str(exc)) from None
    except OSError as exc:  # h5py cannot open it
        raise InputError(f"cannot read '{h5}' (damaged?): {type(exc).__name__}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - the frames are there but not whole
        raise InputError(f"'{h5}': its /frames (or /walls) cannot be read "
                         f"({type(exc).__name__}: {exc}); damaged, or written by another "
                         "version") from None


def _choose_format(out: Path | None, fmt: str | None) -> str:
    suffix = out.suffix.lower().lstrip(".") if out is not None else ""
    if suffix and suffix not in FORMATS:  # DIR/results.h5 or config.toml would be overwritten
        raise InputError(f"--out {out} ends in .{suffix}, not a video's suffix; give a file "
                         f"name ending in {' or '.join('.' + f for f in FORMATS)}")
    if fmt is not None:
        if not isinstance(fmt, str):
            raise InputError(f"--format must be one of {', '.join(FORMATS)}; got {fmt!r}")
        fmt = fmt.lower()
        if fmt not in FORMATS:
            raise InputError(f"--format must be one of {', '.join(FORMATS)}; got '{fmt}'")
        if suffix in FORMATS and suffix != fmt:
            raise InputError(f"--out {out} ends in .{suffix} but --format is {fmt}")
        return fmt
    return suffix if suffix in FORMATS else "mp4"


@dataclass
class AnimationPlan:
    """A checked request: the frames to draw and where to write them."""

    frames: Frames
    out: Path
    fmt: str
    color: str
    fps: int


def _refuse_special_file(out_path: Path | None) -> None:
    """Refuse an --out that is a device, a pipe or a socket: '--out /dev/null' wrote the video
    to /dev/null.mp4 (a name without a suffix gets one), a new file among the devices."""
    try:
        special = out_path is not None and out_path.exists() \
            and not (out_path.is_file() or out_path.is_dir())
    except (OSError, ValueError):
        return  # (the checks below name what is wrong with the path)
    if special:
        raise InputError(f"--out {out_path} is not a regular file (a device, a pipe or a "
                         "socket); give the video's file name")


def plan_animation(run_dir: Path | str, out: Path | str | None = None, *,
                   color: str = "velocity", fmt: str | None = None,
                   fps: int = 10) -> AnimationPlan:
    """Check the request and read the frames; every bad input is an InputError (one line)."""
    for value, name in ((run_dir, "the results folder"), (out, "--out")):
        if not (isinstance(value, str | Path) or (value is None and name == "--out")):
            raise InputError(f"{name} must be a path; got {value!r}")
    if color not in ANIMATION_COLORS:
        raise InputError(f"--color must be one of {', '.join(ANIMATION_COLORS)}; got '{color}'")
    if isinstance(fps, bool) or not isinstance(fps, int) or not 1 <= fps <= 60:
        raise InputError(f"--fps must be an integer from 1 to 60; got {short_repr(fps)}")
    out_path = Path(out) if out is not None else None
    fmt = _choose_format(out_path, fmt)
    _refuse_special_file(out_path)
    if out_path is not None and out_path.name and not out_path.suffix \
            and not out_path.is_dir():  # "--out movie": movie.mp4, which players recognise
        out_path = out_path.with_name(f"{out_path.name}.{fmt}")
    frames = load_run_frames(run_dir)
    if out_path is None:
        out_path = Path(run_dir) / f"animation.{fmt}"
    try:
        if out_path.is_dir() or not out_path.name:
            raise InputError(f"--out {out_path} is a folder; give the video's file name "
                             f"(e.g. {out_path / f'animation.{fmt}'})")
        if not out_path.parent.is_dir():
            what = "is not a folder" if out_path.parent.exists() else "does not exist"
            raise InputError(f"--out {out_path}: '{out_path.parent}' {what}")
        probe = _temporary(out_path, fmt)
        probe.touch()
        probe.unlink()
    except OSError as exc:  # before rendering, not after
        raise InputError(f"--out {out_path}: cannot write there ({exc.strerror})") from None
    return AnimationPlan(frames, out_path, fmt, color, fps)


def render_animation(plan: AnimationPlan,
                     on_frame: Callable[[int, int], None] | None = None) -> AnimationResult:
    """Draw every frame and encode the video; ``on_frame(done, total)`` after each frame.  A
    frame that cannot be read (a segment file damaged: ``DamagedFramesError``) is an
    InputError (one line naming the file), and no video is left."""
    try:
        return _render(plan, on_frame)
    except NoFramesError as exc:  # (read a block at a time, as the frames are drawn)
        raise InputError(str(exc)) from None


def _render(plan: AnimationPlan,
            on_frame: Callable[[int, int], None] | None) -> AnimationResult:
    from silodem.viz.draw import FrameArtist

    t0 = time.perf_counter()
    frames, fmt, out_path = plan.frames, plan.fmt, plan.out
    artist = FrameArtist(frames, plan.color,
                         height_px=_MP4_HEIGHT if fmt == "mp4" else _GIF_HEIGHT)
    total = len(frames)

    def pictures():
        for k, frame in enumerate(frames):
            artist.draw(frame)
            yield artist.rgb()
            if on_frame is not None:
                on_frame(k + 1, total)

    with atomic_file(out_path, _temporary(out_path, fmt)) as tmp:
        if fmt == "mp4":
            _write_mp4(tmp, pictures(), plan.fps)
        else:
            _write_gif(tmp, pictures(), plan.fps)
    played = plan.fps if fmt == "mp4" else 100.0 / gif_delay_cs(plan.fps)
    return AnimationResult(out_path, total, time.perf_counter() - t0, artist.width_px,
                           artist.height_px, played)


def _temporary(out_path: Path, fmt: str) -> Path:
    """The video's temporary file while it is rendered, with the format's suffix."""
    return out_path.with_name(f".{out_path.stem}.tmp.{fmt}")


def _write_mp4(path: Path, pictures, fps: int) -> None:
    import imageio.v2 as imageio

    writer = imageio.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                pixelformat="yuv420p", quality=7, macro_block_size=16,
                                ffmpeg_log_level="error")
    try:
        for rgb in pictures:
            writer.append_data(rgb)
    finally:
        writer.close()


def gif_delay_cs(fps: int) -> int:
    """A GIF frame's delay [1/100 s] nearest to ``1 / fps``: GIF stores whole hundredths of
    a second (Pillow rounds its milliseconds down to them), and browsers play delays under
    2/100 s slower, so at most 50 frames per second (15 fps plays at 100 / 7 = 14.3)."""
    return max(2, round(100 / fps))


def _write_gif(path: Path, pictures, fps: int) -> None:
    from PIL import Image

    fast = Image.Quantize.FASTOCTREE
    images = [Image.fromarray(np.ascontiguousarray(rgb)).quantize(colors=255, method=fast)
              for rgb in pictures]
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:],
                   duration=10 * gif_delay_cs(fps), loop=0, optimize=False, disposal=1)
