"""Which code made a result: a digest of the silodem source files that compute a run.

``__version__`` stays 0.1.0 while the code changes under it, so a study resumed after an
update would mix runs computed by two engines without a word.  The digest below changes with
any change to the files that compute a run's results.h5 (the engine, the silo procedure, the
measurements, the theory, the config and the shipped scenarios), not with the command line,
the report, the figures, the studies' planning or the validation suite.  It is written into
every results.h5 (attribute ``silodem_source``) and checkpoint; a sweep compares it with its
finished runs' (``study.api``), a resume with its checkpoint's (``run``).
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
SHIPPED = ("*.py", "*.toml", "*.in")  # the kinds of file whose content makes the results
# folders whose files present, plan or check results but do not compute a run's results.h5
NOT_COMPUTING = ("cli", "report", "viz", "study", "studies", "validate", "benchmarks")
DIGEST_CHARS = 16  # hex characters kept: 64 bits, plenty to tell versions apart
UNKNOWN = "unknown"  # the digest where the files cannot be read (compared with nothing)


def _computing_files() -> list[Path]:
    """The shipped files under ``PACKAGE`` that compute a run, sorted: regular files, not in
    a hidden folder or one of ``NOT_COMPUTING``, not hidden themselves (an editor's lock or
    backup file), not bytecode caches."""
    out = set()
    for pattern in SHIPPED:
        for path in PACKAGE.rglob(pattern):
            parts = path.relative_to(PACKAGE).parts
            if parts[0] in NOT_COMPUTING or "__pycache__" in parts \
                    or any(p.startswith(".") for p in parts) or not path.is_file():
                continue
            out.add(path)
    return sorted(out)


@functools.cache
def source_digest() -> str:
    """The first ``DIGEST_CHARS`` hex characters of SHA-256 over the files that compute a run
    (``_computing_files``: their paths relative to the package and their bytes, with CRLF
    line ends read as LF), in sorted order: the same on any machine with the same files,
    whatever their modification times, line-end convention or bytecode caches.  ``UNKNOWN``
    where a file cannot be read."""
    h = hashlib.sha256()
    try:
        for path in _computing_files():
            name = path.relative_to(PACKAGE).as_posix().encode()
            data = path.read_bytes().replace(b"\r\n", b"\n")
            h.update(len(name).to_bytes(8, "little") + name + len(data).to_bytes(8, "little"))
            h.update(data)
    except OSError:
        return UNKNOWN
    return h.hexdigest()[:DIGEST_CHARS]


def other_code(recorded: object) -> str | None:
    """``recorded`` (a ``silodem_source`` read back from a file: str, bytes or None) where it
    names other code than this: a known digest that is not :func:`source_digest`; else None
    (not recorded, ``UNKNOWN`` on either side, or this code's)."""
    if isinstance(recorded, bytes):
        recorded = recorded.decode(errors="replace")
    ours = source_digest()
    if recorded is None or UNKNOWN in (str(recorded), ours) or str(recorded) == ours:
        return None
    return str(recorded)
