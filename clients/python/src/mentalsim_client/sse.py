"""A server-sent events parser (the WHATWG event stream format), for job event streams."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class ServerSentEvent:
    """One dispatched event: its ``id`` (the last one set, if any), ``event`` type (``message``
    when none was given), ``data`` (data lines joined by newlines) and ``retry`` (ms), if set."""

    id: str | None
    event: str
    data: str
    retry: int | None = None


def parse_sse(lines: Iterable[str]) -> Iterator[ServerSentEvent]:
    """The events of a stream given line by line (without line terminators).

    Comments (lines starting with ``:``, the service's keep-alives) are skipped; a blank line
    dispatches the event being built; an event with no data is not dispatched, as the format
    says. An event cut off by the end of the stream (no blank line after it) is dropped: it may
    be incomplete.
    """
    last_id: str | None = None
    event = ""
    data: list[str] = []
    retry: int | None = None
    for raw in lines:
        line = raw.rstrip("\r\n")
        if line == "":
            if data:
                yield ServerSentEvent(last_id, event or "message", "\n".join(data), retry)
            event, data, retry = "", [], None
            continue
        if line.startswith(":"):
            continue
        name, sep, value = line.partition(":")
        if sep and value.startswith(" "):
            value = value[1:]
        if name == "data":
            data.append(value)
        elif name == "event":
            event = value
        elif name == "id":
            if "\0" not in value:
                last_id = value
        elif name == "retry":
            if value.isdigit():
                retry = int(value)
