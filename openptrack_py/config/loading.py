"""Reading configs: YAML files, ``--set key.path=value`` overrides, validation.

Validation errors are rewritten so that each names its key path, the allowed values and
the value received (see :func:`validate_config`); YAML and file errors name the file.
"""

from __future__ import annotations

import difflib
import typing
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Annotated, Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from openptrack_py.config.network import NetworkConfig
from openptrack_py.errors import ConfigError

M = TypeVar("M", bound=BaseModel)


def parse_override_value(text: str) -> Any:
    """Parse an override's value as a YAML scalar or flow collection."""
    try:
        return yaml.safe_load(text) if text.strip() else ""
    except yaml.YAMLError:
        return text


def apply_overrides(data: dict[str, Any], overrides: Iterable[str]) -> dict[str, Any]:
    """Apply ``key.path=value`` overrides to a raw config mapping.

    Path chunks index mappings by key and lists by position, or by the ``id`` / ``name``
    of their items (``sensors.kinect_a.rate_hz=15``). Missing mappings are created.

    Raises
    ------
    ConfigError
        If an override is not ``key=value`` or its path cannot be followed.
    """
    for override in overrides:
        path, sep, text = override.partition("=")
        if not sep or not path.strip():
            raise ConfigError(f"override {override!r}: expected key.path=value")
        chunks = path.strip().split(".")
        node: Any = data
        for i, chunk in enumerate(chunks):
            where = ".".join(chunks[: i + 1])
            last = i == len(chunks) - 1
            if isinstance(node, dict):
                if last:
                    node[chunk] = parse_override_value(text)
                else:
                    if node.get(chunk) is None:
                        node[chunk] = {}
                    node = node[chunk]
            elif isinstance(node, list):
                index = _list_index(node, chunk, where)
                if last:
                    node[index] = parse_override_value(text)
                else:
                    node = node[index]
            else:
                parent = ".".join(chunks[:i])
                raise ConfigError(f"override {override!r}: {parent} is not a mapping or list")
    return data


def _list_index(items: list, chunk: str, where: str) -> int:
    if chunk.lstrip("-").isdigit():
        index = int(chunk)
        if -len(items) <= index < len(items):
            return index % len(items)
        raise ConfigError(f"{where}: index out of range (list has {len(items)} items)")
    for index, item in enumerate(items):
        if isinstance(item, dict) and chunk in (item.get("id"), item.get("name")):
            return index
    names = [str(it.get("id", it.get("name"))) for it in items if isinstance(it, dict)]
    raise ConfigError(f"{where}: no item with id {chunk!r} (known: {', '.join(names) or 'none'})")


def _inner_models(annotation: Any) -> list[type[BaseModel]]:
    """The BaseModel classes reachable from a field annotation (through Optional, list...)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    origin = typing.get_origin(annotation)
    if origin is None:
        return []
    found: list[type[BaseModel]] = []
    for arg in typing.get_args(annotation):
        if origin is Annotated and arg is not typing.get_args(annotation)[0]:
            continue
        found.extend(_inner_models(arg))
    return found


def _model_at(model: type[BaseModel], loc: Sequence[int | str]) -> type[BaseModel] | None:
    current: type[BaseModel] | None = model
    for chunk in loc:
        if current is None:
            return None
        if isinstance(chunk, int):
            continue
        field = current.model_fields.get(chunk)
        if field is None:
            return None
        inner = _inner_models(field.annotation)
        current = inner[0] if inner else None
    return current


def _allowed_text(ctx: dict[str, Any]) -> str | None:
    for key, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
        if key in ctx:
            return f"must be {op} {ctx[key]}"
    if "expected" in ctx:
        return f"must be one of {ctx['expected']}"
    if "pattern" in ctx:
        return f"must match {ctx['pattern']}"
    return None


def _format_error(root: type[BaseModel], err: dict[str, Any], data: Any) -> str:
    loc = [c for c in err["loc"] if not (isinstance(c, str) and c.startswith("function-"))]
    where = ".".join(str(c) for c in loc) or "(top level)"
    received = err.get("input")
    if err["type"] == "extra_forbidden":
        parent = _model_at(root, loc[:-1])
        allowed = sorted(parent.model_fields) if parent else []
        hint = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        did_you_mean = f"; did you mean {hint[0]!r}?" if hint else ""
        return f"{where}: unknown key{did_you_mean} (allowed: {', '.join(allowed)})"
    if err["type"] == "missing":
        return f"{where}: required key is missing"
    ctx = err.get("ctx") or {}
    text = _allowed_text(ctx)
    if text is None:
        text = err["msg"]
        text = text.removeprefix("Value error, ")
        text = text[0].lower() + text[1:] if text else text
    if err["type"].startswith("literal") or "expected" in ctx:
        return f"{where}: {text} (received {received!r})"
    if isinstance(received, dict) and not loc:
        return f"{where}: {text}"
    return f"{where}: {text} (received {received!r})"


def validate_config(model: type[M], data: Any, source: str = "config") -> M:
    """Validate a raw mapping against ``model``.

    Raises
    ------
    ConfigError
        Listing every problem, one per line, each naming its key path.
    """
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(
            f"{source}: expected a mapping at the top level, got {type(data).__name__}"
        )
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        lines = [_format_error(model, e, data) for e in exc.errors(include_url=False)]
        raise ConfigError(f"{source}: invalid configuration\n  " + "\n  ".join(lines)) from None


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping from ``path``.

    Raises
    ------
    ConfigError
        If the file is missing, unreadable or not YAML.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"{path}:{where}: not valid YAML ({problem})") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(
            f"{path}: expected a mapping at the top level, got {type(data).__name__}"
        )
    return data


def load_config(
    model: type[M], path: str | Path | None = None, overrides: Iterable[str] = ()
) -> M:
    """Load ``model`` from a YAML file (or defaults), apply overrides, validate.

    Parameters
    ----------
    model : type
        The config model, e.g. :class:`NetworkConfig`.
    path : str or Path, optional
        YAML file; the model's defaults are used when omitted.
    overrides : iterable of str
        ``key.path=value`` items applied after reading the file.

    Raises
    ------
    ConfigError
        For unreadable files, bad overrides or invalid values.
    """
    data = read_yaml(path) if path is not None else {}
    return _validate_with_overrides(model, data, overrides, path)


def _validate_with_overrides(
    model: type[M], data: dict[str, Any], overrides: Iterable[str], path: str | Path | None
) -> M:
    """Apply ``overrides`` to ``data`` and validate; errors name the ``--set`` they come from."""
    overrides = list(overrides)
    data = apply_overrides(data, overrides)
    try:
        return validate_config(model, data, str(path) if path is not None else "config")
    except ConfigError as exc:
        blamed = [o for o in overrides if o.partition("=")[0].strip() in str(exc)]
        if not blamed:
            raise
        sets = ", ".join(f"--set {o}" for o in blamed)
        raise ConfigError(f"{exc}\n  (given by {sets})") from None


def load_network(path: str | Path | None = None, overrides: Iterable[str] = ()) -> NetworkConfig:
    """Load a network file (see :class:`NetworkConfig`).

    Raises
    ------
    ConfigError
        For an empty file (a network needs at least its sensors or simulation), and as
        :func:`load_config`.
    """
    data = read_yaml(path) if path is not None else {}
    if path is not None and not data:
        raise ConfigError(
            f"{path}: the network file is empty; it needs at least 'sensors:' (see "
            "'openptrack show-config demo' for a complete example)"
        )
    return _validate_with_overrides(NetworkConfig, data, overrides, path)


def to_yaml(config: BaseModel) -> str:
    """Render a config (defaults included) as YAML."""
    return yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False)
