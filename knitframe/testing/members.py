"""The member check of the conformance kit: a plugin has every attribute and method its protocol declares.

A protocol of :mod:`knitframe.interfaces` declares each member the core calls, optional
capabilities included (as a ``ClassVar`` flag or a method with a default body). A plugin declares
each one itself or inherits it by subclassing the protocol; :func:`check_members` says which are
missing, which methods are not callable and which flags are not booleans.
"""

from __future__ import annotations

import typing
from typing import Any

__all__ = ["protocol_members", "check_members"]


def protocol_members(proto: type) -> set[str]:
    """Names of the attributes and methods ``proto`` (a :class:`typing.Protocol`) declares, inherited
    ones included."""
    members = getattr(proto, "__protocol_attrs__", None)
    if members is None:  # Python < 3.12
        members = typing._get_protocol_attrs(proto)
    return set(members)


def _definition(proto: type, name: str) -> Any:
    """The protocol's own definition of member ``name`` (function, property, value), or None."""
    for klass in proto.__mro__:
        if name in vars(klass):
            return vars(klass)[name]
    return None


def _annotations(proto: type) -> dict[str, str]:
    """Each annotated member's annotation as written (a string: interfaces uses postponed annotations)."""
    out: dict[str, str] = {}
    for klass in reversed(proto.__mro__):
        out.update({k: str(v) for k, v in vars(klass).get("__annotations__", {}).items()})
    return out


def check_members(target: Any, proto: type, what: str) -> None:
    """``target`` (a plugin class or instance) has every member of ``proto``; methods are callable and
    ``ClassVar[bool]`` flags are booleans. ``what`` names the plugin in the message."""
    members = protocol_members(proto)
    missing = sorted(m for m in members if not hasattr(target, m))
    assert not missing, (
        f"{what} lacks {', '.join(missing)} (declare each, or subclass "
        f"knitframe.interfaces.{proto.__name__} for the declared defaults)"
    )
    notes = _annotations(proto)
    for m in sorted(members):
        if m not in notes:  # a method (or a property) of the protocol
            if not isinstance(_definition(proto, m), property):
                assert callable(getattr(target, m)), f"{what}: {m} must be callable"
        elif notes[m] == "ClassVar[bool]":
            assert isinstance(getattr(target, m), bool), f"{what}: {m} must be True or False"
