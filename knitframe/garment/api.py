"""``knitframe.design(...)``: the Python twin of ``knitframe design`` and the ``[design]`` stage."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["design"]


def design(
    limb: Any = "example",
    library: Any = "builtin",
    objective: Any = "pressure_profile",
    *,
    out: str | Path | None = None,
    overwrite: bool = False,
    **options: Any,
):
    """Design a compression sleeve; returns the :class:`~knitframe.garment.core.Design`.

    Runs the same ``[design]`` stage as a config, so the checks, the outputs and the result are
    the same as ``knitframe design``.

    Parameters
    ----------
    limb : "example", a scan path, a dict of measurements, or a Limb
        A dict holds ``positions_mm``, ``circumferences_mm`` and optionally ``ellipticity``.
    library : "builtin", a library.json path, or a FabricLibrary
    objective : str or dict
        An objective plugin name, or a table with ``kind`` and its options
        (``{"kind": "pressure_profile", "target_mmHg": 30}``).
    out : path, optional
        Write ``design.json``, ``knit-map.csv``/``.png``, ``pressure.png`` and ``design.vtu`` there.
    **options
        The other keys of the ``[design]`` table: ``method``, ``pressure``, ``min_courses``,
        ``max_fabrics``, ``base``, ``stations``, ``around``, ``axis`` and ``tube`` (a dict).
    """
    from knitframe.pipeline import Pipeline

    table: dict[str, Any] = {"objective": objective, **options}
    given = {}
    if isinstance(limb, (str, Path, dict)):
        table["limb"] = str(limb) if isinstance(limb, Path) else limb
    else:
        given["limb"] = limb
    if isinstance(library, (str, Path)):
        table["library"] = str(library)
    else:
        given["library"] = library
    pipeline = Pipeline({"design": table}, base_dir=Path.cwd())
    if given:  # a Limb or FabricLibrary object given directly replaces what the table named
        import attrs

        pipeline.stages = [attrs.evolve(s, **given) if s.name == "design" else s for s in pipeline.stages]
    result = pipeline.run(out, overwrite=overwrite)
    return result.objects["design"]
