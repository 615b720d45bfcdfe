"""The library record: :class:`FabricLibrary`, its checks, library.json in and out, and building from fits."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs

from knitframe.errors import ConfigError
from knitframe.garment.library.checks import check_string, gauge_pair, is_number, json_path, short_repr
from knitframe.garment.library.entry import FabricEntry
from knitframe.garment.library.fits import fit_entries
from knitframe.garment.library.reading import read_json

__all__ = ["LIBRARY_FORMAT", "FabricLibrary"]

#: version written as ``knitframe_library`` and the only one :meth:`FabricLibrary.from_json` reads
LIBRARY_FORMAT = 1


@attrs.frozen
class FabricLibrary:
    """Named candidate fabrics (unique names), with where they came from."""

    name: str
    entries: tuple[FabricEntry, ...] = attrs.field(converter=tuple)
    source: str = ""

    def __attrs_post_init__(self) -> None:
        check_string(self.name, "library.name")
        check_string(self.source, "library.source", empty=True)
        if not self.entries:
            raise ConfigError("library.entries", "the library has no entries")
        seen: dict[str, int] = {}
        for i, e in enumerate(self.entries):
            if not isinstance(e, FabricEntry):
                raise ConfigError(f"library.entries[{i}]", f"expected a FabricEntry, got {short_repr(e)}")
            if e.name in seen:
                raise ConfigError(
                    f"library.entries[{i}].name", f"duplicate name '{e.name}' (also entries[{seen[e.name]}])"
                )
            seen[e.name] = i

    def __len__(self) -> int:
        return len(self.entries)

    def __iter__(self):
        return iter(self.entries)

    def __getitem__(self, key: int | str) -> FabricEntry:
        """An entry by position or by name; an unknown name raises KeyError listing the names."""
        if isinstance(key, str):
            for e in self.entries:
                if e.name == key:
                    return e
            raise KeyError(f"no fabric '{key}' in library '{self.name}'; have {', '.join(self.names)}")
        return self.entries[key]

    @property
    def names(self) -> list[str]:
        """Entry names in library order."""
        return [e.name for e in self.entries]

    def with_gauges(self, gauges: Mapping[str, Any], field: str = "design.gauge") -> FabricLibrary:
        """This library with the pitches of knitter's gauges: ``gauges`` maps a fabric name to
        ``(stitches_per_10cm, courses_per_10cm)`` of a relaxed swatch (:meth:`FabricEntry.with_gauge`);
        the other entries are kept.

        An unknown name (the names are listed), a value that is not a pair, or a number that is not
        finite and > 0 is refused in one line naming ``field.<name>``.
        """
        if not isinstance(gauges, Mapping):
            raise ConfigError(
                field, f"expected a table of fabric name = [stitches, courses], got {short_repr(gauges)}"
            )
        given = dict(gauges)
        for name, value in given.items():
            where = json_path(field, str(name))
            if name not in self.names:
                raise ConfigError(
                    where, f"no fabric '{name}' in library '{self.name}'; have {', '.join(self.names)}"
                )
            given[name] = gauge_pair(value, where)
        entries = [
            e.with_gauge(*given[e.name], path=json_path(field, e.name)) if e.name in given else e
            for e in self
        ]
        return attrs.evolve(self, entries=tuple(entries))

    def to_json(self) -> dict[str, Any]:
        """Plain data as in library.json."""
        return {
            "knitframe_library": LIBRARY_FORMAT,
            "name": self.name,
            "source": self.source,
            "entries": [e.to_json() for e in self.entries],
        }

    @classmethod
    def from_json(cls, data: Any, path: str = "library", *, source: str | None = None) -> FabricLibrary:
        """Check library.json data (one-line ConfigError naming the JSON path of the first bad field) and
        build it."""
        if not isinstance(data, Mapping):
            raise ConfigError(path, f"expected a JSON object, got {short_repr(data)}", source=source)
        if "knitframe_library" not in data:
            raise ConfigError(
                json_path(path, "knitframe_library"),
                "required key is missing (not a knitframe library file)",
                source=source,
            )
        version = data["knitframe_library"]
        if not is_number(version) or version != LIBRARY_FORMAT:
            raise ConfigError(
                json_path(path, "knitframe_library"),
                f"unsupported library format {short_repr(version)}; "
                f"this knitframe reads format {LIBRARY_FORMAT}",
                source=source,
            )
        keys = ("knitframe_library", "name", "source", "entries")
        unknown = sorted(set(data) - set(keys))
        if unknown:
            raise ConfigError(
                json_path(path, str(unknown[0])),
                f"unknown key; a library has {', '.join(keys)}",
                source=source,
            )
        for key in ("name", "entries"):
            if key not in data:
                raise ConfigError(json_path(path, key), "required key is missing", source=source)
        name = check_string(data["name"], json_path(path, "name"), source=source)
        lib_source = check_string(
            data.get("source", ""), json_path(path, "source"), empty=True, source=source
        )
        raw = data["entries"]
        if not isinstance(raw, list):
            raise ConfigError(
                json_path(path, "entries"),
                f"expected a list of entries, got {short_repr(raw)}",
                source=source,
            )
        if not raw:
            raise ConfigError(json_path(path, "entries"), "the library has no entries", source=source)
        entries, seen = [], {}
        for i, item in enumerate(raw):
            where = f"{json_path(path, 'entries')}[{i}]"
            entry = FabricEntry.from_json(item, where, source=source)
            if entry.name in seen:
                raise ConfigError(
                    json_path(where, "name"),
                    f"duplicate name '{entry.name}' (also entries[{seen[entry.name]}])",
                    source=source,
                )
            seen[entry.name] = i
            entries.append(entry)
        return cls(name, tuple(entries), lib_source)

    def save(self, path: str | Path) -> None:
        """Write library.json (UTF-8, indented; never NaN or Infinity)."""
        text = json.dumps(self.to_json(), indent=2, ensure_ascii=False, allow_nan=False)
        Path(path).write_text(text + "\n", encoding="utf-8")

    @classmethod
    def load(cls, path: str | Path) -> FabricLibrary:
        """Read and check a library.json; errors name the file and the JSON path."""
        p = Path(path)
        return cls.from_json(read_json(p, "library file"), "library", source=str(p))

    @classmethod
    def from_fits(
        cls,
        params_files: Sequence[str | Path],
        *,
        names: Any = None,
        course_pitch: Any = None,
        wale_pitch: Any = None,
        max_tension: Any = None,
        max_stretch: Any = None,
        pattern: Any = None,
        yarn: Any = None,
        stitch_length: Any = None,
        arc_length: Any = None,
        source: Any = None,
        pitch_source: Any = None,
        gauge: Any = None,
        pitch_measured: Any = None,
        tension_scatter: Any = None,
        name: str = "library",
        library_source: str = "",
    ) -> FabricLibrary:
        """A library with one entry per fitted model (a ``params.json`` of ``knitframe fit`` or a ``[fit]``
        stage).

        Every keyword takes one value for all files or a sequence of one value per file.
        ``pattern``, ``yarn``, ``stitch_length``, ``arc_length`` and ``names`` come from the params
        file's metadata where present (its ``fabric`` table, else its top level: ``pattern``,
        ``yarn``, ``stitch_length``, ``arc_length``, ``name``), else from these keywords; both given
        and different is an error. ``names`` defaults to the params file's folder name (or its
        stem without ``-params``). ``gauge`` is a knitter's gauge ``(stitches_per_10cm,
        courses_per_10cm)`` of a relaxed swatch (one pair for all files, or a sequence of one pair or
        None per file); it gives the pitches (course 100/stitches, wale 100/courses mm) and cannot be
        given with them. Pitches not given are estimated by Munden's plain-knit relations
        from the arc length, or from the stitch length through the pattern's stitch-length table.
        ``pitch_measured`` records whether the pitches were measured; by default, true when both
        pitches or a gauge are given and false when any is estimated. ``tension_scatter`` (default
        None) is the scatter of the course tests' repeats (:attr:`FabricEntry.tension_scatter`).
        ``max_tension`` is required; ``max_stretch`` is optional. ``source`` defaults to the fit's
        model, fitter, data labels and NRMSE. A fit with a parameter at a bound warns.
        """
        entries = fit_entries(
            params_files,
            names=names,
            course_pitch=course_pitch,
            wale_pitch=wale_pitch,
            max_tension=max_tension,
            max_stretch=max_stretch,
            pattern=pattern,
            yarn=yarn,
            stitch_length=stitch_length,
            arc_length=arc_length,
            source=source,
            pitch_source=pitch_source,
            gauge=gauge,
            pitch_measured=pitch_measured,
            tension_scatter=tension_scatter,
        )
        return cls(name, tuple(entries), library_source)
