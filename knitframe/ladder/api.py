"""The Python twin of ``knitframe ladder``: :func:`ladder` runs a config's pipeline with the
``[ladder]`` stage and gives back a :class:`LadderResult`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs

from knitframe.records import Response


@attrs.frozen
class LadderResult:
    """What a ladder run gives back: a row per rung (as in ``ladder.csv``) and the curves."""

    #: one dict per rung, keys as :data:`CSV_COLUMNS`
    rows: list[dict[str, Any]]
    #: each finished rung's Response, by rung name
    curves: dict[str, Response]
    #: the measured curves compared against
    measured: list[Response]
    #: the best rung that ran
    reference: str | None
    #: the Markdown table
    table: str
    out: Path | None = None

    def row(self, rung: str) -> dict[str, Any]:
        """The row of one rung."""
        return next(r for r in self.rows if r["rung"] == rung)


def ladder_config(
    config: str | Path | Mapping[str, Any],
    *,
    rungs: Sequence[str] | None = None,
    max_time: float | None = None,
) -> tuple[dict[str, Any], Path, str | None]:
    """A config with its ``[ladder]`` table given or amended: ``(config, base_dir, source)``."""
    from knitframe.config import load_toml

    if isinstance(config, Mapping):
        data, base, source = dict(config), Path.cwd(), None
    else:
        path = Path(config)
        data, base, source = load_toml(path), path.resolve().parent, str(path)
    table = dict(data.get("ladder", {})) if isinstance(data.get("ladder", {}), Mapping) else data["ladder"]
    if isinstance(table, dict):
        if rungs is not None:
            table["rungs"] = list(rungs)
        if max_time is not None:
            table["max_time"] = max_time
    data["ladder"] = table
    return data, base, source


def ladder(
    config: str | Path | Mapping[str, Any],
    out: str | Path | None = None,
    *,
    rungs: Sequence[str] | None = None,
    max_time: float | None = None,
    overwrite: bool = False,
    quiet: bool = True,
) -> LadderResult:
    """Run a config's pipeline with the ladder stage; the Python twin of ``knitframe ladder``.

    Parameters
    ----------
    config : path or mapping
        A TOML file or parsed dict with ``[fabric]`` and ``[scene]`` (and ``[data]`` for measured
        curves); its ``[ladder]`` table, if any, is amended by ``rungs`` and ``max_time``.
    out : path, optional
        Writes ``ladder.csv``, ``ladder.md``, ``ladder.png``, ``curves.png`` and
        ``ladder-curves.csv`` there; None keeps no files.
    rungs : names from :data:`RUNGS`; default :data:`DEFAULT_RUNGS`.
    max_time : float, optional
        Skip the rungs whose estimated time exceeds this many seconds.
    """
    from knitframe.pipeline import Pipeline

    data, base, source = ladder_config(config, rungs=rungs, max_time=max_time)
    result = Pipeline(data, base_dir=base, source=source).run(out, overwrite=overwrite, quiet=quiet)
    return attrs.evolve(result.objects["ladder"], out=result.out)
