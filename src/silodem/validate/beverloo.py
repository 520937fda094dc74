"""Beverloo discharge rates (work in progress)."""

from __future__ import annotations

from silodem.validate.records import Record


def run(quick: bool = False) -> tuple[list[Record], dict]:
    return [], {}
