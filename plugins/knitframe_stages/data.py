"""Stage ``[data]``: import test files as Responses through a reader plugin.

::

    [data]
    reader = "auto"     # chosen from each file's header; or "singal2024",
                        # or { kind = "generic", average = false }
    files = ["cotton-stockinette-x.csv"]

Writes ``responses.csv`` and ``responses.png``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs

from knitframe import hookimpl
from knitframe.config import PluginSpec, instantiate
from knitframe.errors import ConfigError, FieldError
from knitframe.interfaces import DispatchingReader, Stage
from knitframe.records import Response
from knitframe.report import plot_responses, write_responses_csv
from knitframe.schema import build


@attrs.frozen
class DataTable:
    """Schema of the ``[data]`` table."""

    #: data files, relative to the config file
    files: list[str]
    #: reader plugin name ("auto": chosen from each file's header), or a table with ``kind`` and options
    reader: str | dict[str, Any] = "auto"

    def __attrs_post_init__(self) -> None:
        if not self.files:
            raise FieldError("files", "must list at least one file")


@attrs.frozen
class DataStage(Stage):
    """Import measured curves as Responses."""

    name: ClassVar[str] = "data"
    description: ClassVar[str] = "import test files as Responses through a reader plugin"
    order: ClassVar[int] = 10
    uses: ClassVar[tuple[str, ...]] = ()
    schema: ClassVar[type] = DataTable

    reader_name: str
    responses: tuple[Response, ...]
    #: the readers the ``auto`` reader chose, one per file
    chosen: tuple[str, ...] = ()

    @classmethod
    def from_config(cls, config, ctx) -> DataStage:
        table = build(DataTable, config["data"], "data", source=ctx.source)
        reader = instantiate(ctx.registry, "reader", table.reader, "data.reader", source=ctx.source)
        responses: list[Response] = []
        chosen: list[str] = []
        for i, f in enumerate(table.files):
            path = ctx.path(f, f"data.files[{i}]")
            if isinstance(reader, DispatchingReader):  # the auto reader: record which reader each file got
                file_reader = reader.reader_for(path)
                chosen.append(file_reader.name)
                responses.extend(file_reader.read(path))
            else:
                responses.extend(reader.read(path))  # DataError names the file, line and column
        if not responses:
            raise ConfigError("data.files", "the files hold no curves", source=ctx.source)
        return cls(PluginSpec.parse(table.reader, "data.reader").kind, tuple(responses), tuple(chosen))

    def run(self, ctx) -> None:
        ctx.used("reader", self.reader_name)
        for name in dict.fromkeys(self.chosen):
            ctx.used("reader", name)
        ctx.used("stage", self.name)
        ctx.responses.extend(self.responses)
        write_responses_csv(ctx.output("responses.csv"), self.responses)
        plot_responses(ctx.output("responses.png"), self.responses, title="imported responses")
        ctx.results[self.name] = {
            "curves": [
                {"label": r.label, "load": r.load, "points": len(r), "samples": r.n_samples}
                for r in self.responses
            ],
            "headline": f"{len(self.responses)} curves imported",
        }


@hookimpl
def register_stages(register):
    register(DataStage)
