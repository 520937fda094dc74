"""Which code made a result: a digest of silodem's own source files.

``__version__`` stays 0.1.0 while the code changes under it, so a study resumed after an
update would mix runs computed by two engines without a word.  The digest below changes with
any change to the package's source (its ``.py`` files and the scenario, study and benchmark
files it ships), and is written into every results.h5 (attribute ``silodem_source``); a sweep
compares it with its finished runs' (``study.api``).
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
SHIPPED = ("*.py", "*.toml", "*.in")  # the files whose content makes the results
DIGEST_CHARS = 16  # hex characters kept: 64 bits, plenty to tell versions apart


@functools.cache
def source_digest() -> str:
    """The first ``DIGEST_CHARS`` hex characters of SHA-256 over the package's shipped files
    (their paths relative to the package, and their bytes), in sorted order; the same on any
    machine with the same files, whatever their modification times or the interpreter's
    bytecode caches."""
    h = hashlib.sha256()
    files = sorted({p for pattern in SHIPPED for p in PACKAGE.rglob(pattern)
                    if "__pycache__" not in p.parts})
    for path in files:
        name = path.relative_to(PACKAGE).as_posix().encode()
        data = path.read_bytes()
        h.update(len(name).to_bytes(8, "little") + name + len(data).to_bytes(8, "little"))
        h.update(data)
    return h.hexdigest()[:DIGEST_CHARS]
