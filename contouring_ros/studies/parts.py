"""Saved benchmark parts (``benchmark --save-part``, ``--from-parts``) in a format that cannot run code.

A part is an object graph of dataclasses (the benchmark's Part, Row, Family, Combination, Excluded and
Reference, the tuning's Protocol, Tuned, Evaluation and Outcome, the loop margins ...) holding numbers,
strings, lists, tuples and dicts. It is written as gzip-compressed JSON:

* a header line ``{"format": "contouring_ros benchmark part", "version": 1, "sha256": ..., "bytes": ...}``,
  then the payload's JSON text, whose SHA-256 and length the header states;
* in the payload every dataclass is ``{"$": "obj", "class": "<module>.<Class>", "id": n, "fields": {...}}``
  with its fields taken from :func:`dataclasses.fields` (a field added to a class later is carried without
  any change here), a second mention of the same object ``{"$": "ref", "id": n}`` (rows share their family,
  and the proposed row refers to itself); tuples, dicts (any key type), non-finite floats, numpy scalars and
  arrays carry a tag of their own.

Reading checks, before any object is built: the file's size and its decompressed size against stated
limits, the header, the version, the length and the checksum of the payload; then, while building: that
every class named is on the allow-list :data:`CLASSES` (nothing is imported or called from the file: the
classes are looked up in that dict) and every value has the type its field declares. Anything else is one
:class:`~contouring_ros.errors.ConfigError` line naming the file and what is wrong in it.
"""
from __future__ import annotations

import dataclasses
import gzip
import hashlib
import io
import json
import math
import typing
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..records.outputs import write_atomically

__all__ = ["FORMAT", "VERSION", "MAX_FILE_BYTES", "MAX_TEXT_BYTES", "CLASSES", "register", "dumps", "loads", "save", "load"]

FORMAT = "contouring_ros benchmark part"
VERSION = 1
MAX_FILE_BYTES = 256 * 2**20        # a part file's size on disk, at most (the papers' whole benchmark: ~2 MB)
MAX_TEXT_BYTES = 1024 * 2**20       # its decompressed JSON, at most (a gzip bomb stops here)
_NUMPY_KINDS = "biuf"               # numpy scalars and arrays of bools, integers and floats only


#: class name -> class: every dataclass a part may hold, the only classes :func:`loads` builds; registered by
#: the modules that define them (:func:`register`: contouring_ros.studies.benchmark registers the benchmark's), so
#: this module imports none of them
CLASSES: dict = {}


def register(*classes) -> None:
    """Allow ``classes`` (dataclasses) in parts, each under '<module>.<name>'."""
    CLASSES.update({f"{c.__module__.rsplit('.', 1)[-1]}.{c.__qualname__}": c for c in classes})


class _Odd(Exception):
    """A payload that is not what a part holds: the message says where and what."""


# ------------------------------------------------------------------------------------------------ writing


def _encode(value, names: dict, ids: dict):
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.generic):
        if value.dtype.kind not in _NUMPY_KINDS:
            raise TypeError(f"numpy {value.dtype} values are not saved in parts")
        return {"$": "np", "dtype": value.dtype.str, "v": _encode(value.item(), names, ids)}
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else {"$": "float", "v": repr(value)}
    if isinstance(value, list):
        return [_encode(v, names, ids) for v in value]
    if isinstance(value, tuple):
        return {"$": "tuple", "items": [_encode(v, names, ids) for v in value]}
    if isinstance(value, dict):
        return {"$": "dict", "items": [[_encode(k, names, ids), _encode(v, names, ids)] for k, v in value.items()]}
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in _NUMPY_KINDS:
            raise TypeError(f"numpy arrays of {value.dtype} are not saved in parts")
        return {"$": "ndarray", "dtype": value.dtype.str, "shape": list(value.shape),
                "data": [_encode(v, names, ids) for v in value.ravel().tolist()]}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if id(value) in ids:
            return {"$": "ref", "id": ids[id(value)][0]}
        name = names.get(type(value))
        if name is None:
            raise TypeError(f"{type(value).__qualname__} is not on the list of classes a part may hold")
        ids[id(value)] = (len(ids), value)          # the object kept alive, so that its id stays its own
        return {"$": "obj", "class": name, "id": ids[id(value)][0],
                "fields": {f.name: _encode(getattr(value, f.name), names, ids) for f in dataclasses.fields(value)}}
    raise TypeError(f"a {type(value).__qualname__} value cannot be saved in a part")


def dumps(part) -> bytes:
    """``part`` (a benchmark Part) as the bytes of a part file: gzip of the header line and the payload."""
    names = {cls: name for name, cls in CLASSES.items()}
    payload = json.dumps(_encode(part, names, {}), separators=(",", ":"), allow_nan=False).encode()
    header = {"format": FORMAT, "version": VERSION, "sha256": hashlib.sha256(payload).hexdigest(),
              "bytes": len(payload)}
    return gzip.compress(json.dumps(header).encode() + b"\n" + payload, mtime=0)


def save(part, path) -> Path:
    """Write ``part`` to ``path`` beside and moved into place (:func:`~contouring_ros.errors.write_atomically`)."""
    data = dumps(part)
    return write_atomically(Path(path), lambda tmp: tmp.write_bytes(data))


# ------------------------------------------------------------------------------------------------ reading


class _Builder:
    """Builds the objects of a checked payload, checking each value against its field's declared type."""

    def __init__(self):
        self.classes = CLASSES
        self.objects = {}
        self.hints = {}

    def value(self, node, where: str):
        if node is None or isinstance(node, (bool, str, int, float)):
            return node
        if isinstance(node, list):
            return [self.value(v, f"{where}[{i}]") for i, v in enumerate(node)]
        if not isinstance(node, dict):
            raise _Odd(f"{where}: a JSON {type(node).__name__} where a value was expected")
        tag = node.get("$")
        if tag == "float":
            text = node.get("v")
            if text not in ("nan", "inf", "-inf"):
                raise _Odd(f"{where}: {text!r} is not a non-finite float")
            return float(text)
        if tag == "tuple":
            return tuple(self.value(v, f"{where}[{i}]") for i, v in enumerate(self._list(node, "items", where)))
        if tag == "dict":
            out = {}
            for i, pair in enumerate(self._list(node, "items", where)):
                if not isinstance(pair, list) or len(pair) != 2:
                    raise _Odd(f"{where}: entry {i} is not a [key, value] pair")
                key = self.value(pair[0], f"{where} key {i}")
                try:
                    out[key] = self.value(pair[1], f"{where}[{key!r}]")
                except TypeError:
                    raise _Odd(f"{where}: key {i} cannot be a dict key") from None
            return out
        if tag == "np":
            dtype = self._dtype(node, where)
            item = self.value(node.get("v"), where)
            if not isinstance(item, (bool, int, float)):
                raise _Odd(f"{where}: a numpy {dtype} scalar holds {type(item).__name__}")
            return dtype.type(item)
        if tag == "ndarray":
            dtype = self._dtype(node, where)
            shape = self._list(node, "shape", where)
            data = [self.value(v, where) for v in self._list(node, "data", where)]
            if not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in shape) \
                    or math.prod(shape) != len(data) or not all(isinstance(v, (bool, int, float)) for v in data):
                raise _Odd(f"{where}: an array whose shape {shape} does not hold its {len(data)} numbers")
            return np.array(data, dtype=dtype).reshape(shape)
        if tag == "ref":
            if node.get("id") not in self.objects:
                raise _Odd(f"{where}: refers to object {node.get('id')!r}, which comes later or not at all")
            return self.objects[node["id"]]
        if tag == "obj":
            return self.obj(node, where)
        raise _Odd(f"{where}: unknown tag {tag!r}")

    @staticmethod
    def _list(node, key, where):
        value = node.get(key)
        if not isinstance(value, list):
            raise _Odd(f"{where}: {key!r} is not a list")
        return value

    @staticmethod
    def _dtype(node, where):
        try:
            dtype = np.dtype(str(node.get("dtype")))
        except TypeError:
            raise _Odd(f"{where}: {node.get('dtype')!r} is not a numpy dtype") from None
        if dtype.kind not in _NUMPY_KINDS:
            raise _Odd(f"{where}: numpy dtype {dtype} is not one a part holds")
        return dtype

    def obj(self, node, where: str):
        name, ident, values = node.get("class"), node.get("id"), node.get("fields")
        cls = self.classes.get(name) if isinstance(name, str) else None
        if cls is None:
            raise _Odd(f"{where}: class {name!r} is not one a part holds")
        if not isinstance(ident, int) or ident in self.objects:
            raise _Odd(f"{where}: object id {ident!r} is not a new one")
        if not isinstance(values, dict):
            raise _Odd(f"{where}: {name} without its fields")
        fields = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - set(fields))
        if unknown:
            raise _Odd(f"{where}: {name} has no field {unknown[0]!r} (written by another version?)")
        obj = object.__new__(cls)        # registered before its fields: a row may refer to itself
        self.objects[ident] = obj
        hints = self._hints(cls)
        for fname, f in fields.items():
            here = f"{where}.{fname}"
            if fname in values:
                value = self.value(values[fname], here)
            elif f.default is not dataclasses.MISSING:
                value = f.default
            elif f.default_factory is not dataclasses.MISSING:
                value = f.default_factory()
            else:
                raise _Odd(f"{here}: missing (written by another version?)")
            if not _fits(value, hints.get(fname, typing.Any)):
                raise _Odd(f"{here}: a {type(value).__name__} where {name}'s field holds "
                           f"{_spelled(hints.get(fname))}")
            object.__setattr__(obj, fname, value)
        return obj

    def _hints(self, cls) -> dict:
        if cls not in self.hints:
            try:
                self.hints[cls] = typing.get_type_hints(cls)
            except Exception:        # an annotation that does not resolve: its fields are not type-checked
                self.hints[cls] = {}
        return self.hints[cls]


def _fits(value, hint) -> bool:
    """Whether ``value`` is of the declared type ``hint`` (classes, unions, Optional, list/dict/tuple and
    their generics by their origin; anything else: yes)."""
    if hint is typing.Any or hint is object:
        return True
    origin = typing.get_origin(hint)
    if origin is typing.Union or str(origin) == "<class 'types.UnionType'>":
        return any(_fits(value, h) for h in typing.get_args(hint))
    if origin is not None:
        hint = origin
    if hint is type(None):
        return value is None
    if not isinstance(hint, type):
        return True
    if hint is float:
        return isinstance(value, (float, int, np.floating, np.integer)) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    return isinstance(value, hint)


def _spelled(hint) -> str:
    return getattr(hint, "__name__", None) or str(hint).replace("typing.", "")


def _no_constant(name):
    raise ValueError(f"{name} in the JSON text (parts write non-finite floats tagged)")


def loads(data: bytes, name: str = "part"):
    """The object a part file's bytes hold (ConfigError naming ``name`` and what is wrong otherwise): size,
    header, version, length and checksum are checked before anything is built."""
    if len(data) > MAX_FILE_BYTES:
        raise ConfigError(f"{name}: {len(data)} bytes, over the {MAX_FILE_BYTES // 2**20} MiB a part may have")
    if data[:2] != b"\x1f\x8b":
        raise ConfigError(f"{name}: not a benchmark part (written by benchmark --save-part): not gzip data")
    try:
        with gzip.GzipFile(fileobj=io.BytesIO(data)) as stream:
            text = stream.read(MAX_TEXT_BYTES + 1)
    except (OSError, EOFError, ValueError) as error:
        raise ConfigError(f"{name}: not a readable benchmark part ({type(error).__name__}: {error})") from None
    if len(text) > MAX_TEXT_BYTES:
        raise ConfigError(f"{name}: decompresses to over {MAX_TEXT_BYTES // 2**20} MiB, more than a part holds")
    line, _, payload = text.partition(b"\n")
    try:
        header = json.loads(line)
    except (ValueError, RecursionError):
        header = None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise ConfigError(f"{name}: not a benchmark part (written by benchmark --save-part): no part header")
    if header.get("version") != VERSION:
        raise ConfigError(f"{name}: a benchmark part of format version {header.get('version')!r}; this version "
                          f"reads version {VERSION}")
    if header.get("bytes") != len(payload) or header.get("sha256") != hashlib.sha256(payload).hexdigest():
        raise ConfigError(f"{name}: the part's contents do not match its checksum (cut off or changed)")
    try:
        tree = json.loads(payload, parse_constant=_no_constant)
        return _Builder().value(tree, "part")
    except _Odd as error:
        raise ConfigError(f"{name}: odd contents for a benchmark part: {error}") from None
    except (ValueError, RecursionError) as error:
        raise ConfigError(f"{name}: odd contents for a benchmark part ({type(error).__name__}: "
                          f"{str(error)[:200]})") from None


def load(path, name: str | None = None):
    """The object the part file at ``path`` holds (:func:`loads`); ConfigError if it cannot be read."""
    name = name or str(path)
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ConfigError(f"{name}: {size} bytes, over the {MAX_FILE_BYTES // 2**20} MiB a part may have")
        data = path.read_bytes()
    except OSError as error:
        raise ConfigError(f"{name}: cannot read it ({error.strerror or type(error).__name__})") from None
    return loads(data, name)
