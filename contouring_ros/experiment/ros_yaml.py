"""Reading an experiment file as the ROS 2 parameter parser reads it: a YAML loader that refuses aliases,
tags and deep nesting and types every scalar as rcl_yaml_param_parser does (strtoll/strtod, its booleans and
special floats), :func:`read_yaml`, and safe reading of a file of bounded size that is a regular file."""
from __future__ import annotations

import math
import os
import re
import stat
import sys
from pathlib import Path

import yaml

from ..errors import ConfigError
from .schema import MAX_DEPTH, MAX_EVENTS, MAX_FILE_BYTES, MAX_ITEMS, _described, _key_name, _printable, _show

try:    # libyaml's parser (the one the ROS 2 parameter parser uses) when PyYAML has it: 5x faster
    from yaml._yaml import CParser as _CParser
except ImportError:
    _CParser = None
_LOADER_BASES = (yaml.composer.Composer, _CParser, yaml.constructor.SafeConstructor, yaml.resolver.Resolver) \
    if _CParser is not None else (yaml.SafeLoader,)


class _NoAliasLoader(*_LOADER_BASES):
    """YAML loader that refuses anchors/aliases, so no file can expand without bound, and reads every
    exponent float (1e-3, 4.86e7) as a number, as YAML 1.2 and the ROS parameter parser do.

    It also refuses explicit tags (!!float 1: the ROS parser ignores them) and nesting deeper than MAX_DEPTH,
    and names the key of every problem it finds; :meth:`check_ros` holds a document to the ROS parser."""

    _path: list
    _depth = 0

    def __init__(self, text: str):
        if _CParser is None:
            yaml.SafeLoader.__init__(self, text)
            return
        _CParser.__init__(self, text)
        yaml.composer.Composer.__init__(self)
        yaml.constructor.SafeConstructor.__init__(self)
        yaml.resolver.Resolver.__init__(self)

    @property
    def key_path(self) -> list:
        """The keys from the document's root to the node being read ([] before the first), for messages."""
        return getattr(self, "_path", [])

    def _refuse(self, mark, message: str, path=None):
        key = _key_name(self._path if path is None else path)
        raise ConfigError(f"{key + ': ' if key else ''}line {mark.line + 1}: {message}")

    def compose_node(self, parent, index):
        if not hasattr(self, "_path"):
            self._path = []
        event = self.peek_event()
        label = None if parent is None or index is None else (index.value if isinstance(index, yaml.ScalarNode)
                                                               else f"[{index}]")
        if label is not None:
            self._path.append(label)
        self._depth += 1
        try:
            if self.check_event(yaml.AliasEvent):
                self._refuse(event.start_mark, "YAML aliases (*name) are not allowed in experiment files")
            if self._depth > MAX_DEPTH:
                self._refuse(event.start_mark, f"nested deeper than {MAX_DEPTH} levels")
            tag = getattr(event, "tag", None)
            if tag not in (None, "!"):
                self._refuse(event.start_mark, f"explicit YAML tags ({_show(tag)}) are not allowed in experiment "
                                               "files (the ROS 2 parser ignores them)")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1
            if label is not None:
                self._path.pop()

    def fetch_flow_collection_start(self, TokenClass):
        # the scanner's own nesting ([[[[... or {a: {a: ...), refused before its cost grows with the depth
        if self.flow_level >= MAX_DEPTH:
            self._refuse(self.get_mark(), f"nested deeper than {MAX_DEPTH} levels")
        super().fetch_flow_collection_start(TokenClass)

    def check_ros(self, root):
        """Refuse what the ROS 2 parameter parser (rcl_yaml_param_parser) reads differently from this
        loader, or refuses: a scalar of another type or value (bare y/n read as booleans, 1:30, 1_000,
        integers beyond 64 bits, ~ and null, dates, 0x1p3, nan, denormals), an empty value, list or
        mapping, a list of mixed types or of lists or mappings, a key that is not a plain ASCII name."""
        if not isinstance(root, yaml.MappingNode):
            return
        for section_key, section in root.value:
            if not isinstance(section, yaml.MappingNode):
                continue
            for body_key, body in section.value:
                if isinstance(body, yaml.MappingNode):
                    self._check_ros_mapping(body, [section_key.value, body_key.value])

    def _check_ros_mapping(self, node, path):
        if not node.value:
            self._refuse(node.start_mark, "an empty mapping: ROS 2 gives it no value (leave the key out)", path)
        for key_node, value_node in node.value:
            here = path + [key_node.value if isinstance(key_node, yaml.ScalarNode) else "?"]
            key = self._construct(key_node, here) if isinstance(key_node, yaml.ScalarNode) else None
            if not isinstance(key, str):
                self._refuse(key_node.start_mark, f"the key {_show(getattr(key_node, 'value', key_node))} is read "
                                                  f"as {_described(key)}, ROS 2 reads a name: quote it", here)
            if not _PARAMETER_NAME.match(key):
                self._refuse(key_node.start_mark, "a parameter name is 1 to 64 ASCII letters, digits and _ "
                                                  "(not starting with a digit)", here)
            if isinstance(value_node, yaml.MappingNode):
                self._check_ros_mapping(value_node, here)
            elif isinstance(value_node, yaml.SequenceNode):
                self._check_ros_sequence(value_node, here)
            else:
                self._check_ros_scalar(value_node, here)

    def _check_ros_sequence(self, node, path):
        if not node.value:
            self._refuse(node.start_mark, "an empty list: ROS 2 cannot give it a type (leave the key out or "
                                          "give at least one item)", path)
        if len(node.value) > MAX_ITEMS:
            self._refuse(node.start_mark, f"expected at most {MAX_ITEMS} items, got {len(node.value)}", path)
        kinds = []
        for index, item in enumerate(node.value):
            if not isinstance(item, yaml.ScalarNode):
                what = "list" if isinstance(item, yaml.SequenceNode) else "mapping"
                self._refuse(item.start_mark, f"item {index + 1} is a {what}: a ROS 2 list parameter holds plain "
                                              "values only", path)
            kinds.append(self._check_ros_scalar(item, path, index))
        if len(set(kinds)) > 1:
            if set(kinds) == {"integer", "double"}:
                first = kinds.index("integer")
                self._refuse(node.start_mark, f"a list of integers and decimals (item {first + 1} is "
                                              f"{_show(node.value[first].value)}): ROS 2 refuses a list of mixed "
                                              "types; write every number with a decimal point", path)
            self._refuse(node.start_mark, f"a list of mixed types ({', '.join(dict.fromkeys(kinds))}) as ROS 2 "
                                          "reads it: ROS 2 refuses it; quote names that read as booleans (y, n, "
                                          "on, off ...)", path)

    def _construct(self, node, path):
        try:
            return self.construct_object(node)
        except (ValueError, OverflowError) as error:     # e.g. an integer of more than 4300 digits
            self._refuse(node.start_mark, f"cannot read {_show(node.value)} ({_printable(error, 100)})", path)

    def _check_ros_scalar(self, node, path, index=None) -> str:
        kind, ros = _ros_scalar(node.value, node.style)
        where = "" if index is None else f"item {index + 1}: "
        if kind == "empty":
            self._refuse(node.start_mark, f"{where}no value (ROS 2 refuses an empty value)", path)
        ours = self._construct(node, path)
        agree = {"bool": lambda: type(ours) is bool and ours == ros,
                 "integer": lambda: type(ours) is int and ours == ros,
                 "double": lambda: type(ours) is float and (ours == ros or (math.isnan(ours) and math.isnan(ros))),
                 "string": lambda: type(ours) is str and ours == ros}[kind]()
        if not agree:
            hint = {"bool": f"quote it ('{node.value}') for a name", "string": "write a plain number, or quote it "
                    "for a name", "integer": "quote it for a name", "double": "write a plain decimal number, or "
                    "quote it for a name"}[kind]
            if kind == "double" and type(ours) is int:
                hint = "integers are 64-bit in ROS 2"
            if ours is None:
                hint = "give a value or leave the key out"
            self._refuse(node.start_mark, f"{where}ROS 2 reads {_show(node.value)} as {_described(ros, kind)}, not "
                                          f"as {_described(ours)}: {hint}", path)
        return kind


_NoAliasLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))
_PARAMETER_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,63}$")


_PLAIN_INTEGER = re.compile(r"^[-+]?(?:0|[1-9][0-9]{0,17})$")
_PLAIN_DECIMAL = re.compile(r"^[-+]?(?:[0-9]+\.[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]{1,3})?$")
_ROS_TRUE = {"Y", "y", "yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"}
_ROS_FALSE = {"N", "n", "no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"}
_ROS_SPECIAL_FLOATS = {".nan": math.nan, ".NaN": math.nan, ".NAN": math.nan, ".inf": math.inf, ".Inf": math.inf,
                       ".INF": math.inf, "+.inf": math.inf, "+.Inf": math.inf, "+.INF": math.inf,
                       "-.inf": -math.inf, "-.Inf": -math.inf, "-.INF": -math.inf}


def _ros_scalar(value: str, style) -> tuple:
    """How rcl_yaml_param_parser reads one scalar (its get_value: booleans, then C strtol with base 0, then
    strtod, else a string; quoted scalars are strings): (kind, value), kind bool | integer | double |
    string | empty."""
    if style in ("'", '"'):
        return "string", value
    if value == "":
        return "empty", None
    if value in _ROS_TRUE or value in _ROS_FALSE:
        return "bool", value in _ROS_TRUE
    if value in _ROS_SPECIAL_FLOATS:
        return "double", _ROS_SPECIAL_FLOATS[value]
    if _PLAIN_INTEGER.match(value):     # the common forms, read as strtol / strtod read them, without a C call
        return "integer", int(value)
    if _PLAIN_DECIMAL.match(value):
        number = float(value)
        mantissa = re.split("[eE]", value)[0]
        if math.isfinite(number) and (abs(number) >= sys.float_info.min or not re.search("[1-9]", mantissa)):
            return "double", number       # (strtod: a range error for a denormal or an overflow)
    integer = _c_strtol(value)
    if integer is not None:
        return "integer", integer
    number = _c_strtod(value)
    if number is not None:
        return "double", number
    return "string", value


def _libc():
    global _LIBC
    if _LIBC is None:
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            libc.strtoll.restype, libc.strtod.restype = ctypes.c_longlong, ctypes.c_double
            libc.strtoll.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_void_p), ctypes.c_int]
            libc.strtod.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_void_p)]
            _LIBC = (ctypes, libc)
        except (OSError, AttributeError):
            _LIBC = False
    return _LIBC


_LIBC = None


def _c_parse(value: str, call):
    """Run strtoll/strtod on ``value`` as rcl does: the number if it takes the whole text without a range
    error (errno), else None."""
    ctypes, libc = _libc()
    raw = value.encode()
    if b"\0" in raw:
        return None
    buffer = ctypes.create_string_buffer(raw)
    end = ctypes.c_void_p()
    ctypes.set_errno(0)
    number = call(libc, buffer, ctypes.byref(end))
    if ctypes.get_errno() != 0 or end.value is None or end.value - ctypes.addressof(buffer) != len(raw):
        return None
    return number


def _c_strtol(value: str):
    if _libc():
        return _c_parse(value, lambda libc, text, end: libc.strtoll(text, end, 0))
    match = re.fullmatch(r"\s*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)", value)   # no C library: the same rules
    if not match:
        return None
    digits = match.group(2)
    number = int(digits, 16 if digits[:2].lower() == "0x" else 8 if digits.startswith("0") else 10)
    number = -number if match.group(1) == "-" else number
    return number if -2 ** 63 <= number < 2 ** 63 else None


def _c_strtod(value: str):
    if _libc():
        return _c_parse(value, lambda libc, text, end: libc.strtod(text, end))
    if not re.fullmatch(r"\s*[+-]?((\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|inf(inity)?|nan)", value, re.IGNORECASE):
        return None
    number = float(value)
    return number if math.isnan(number) or (math.isinf(number) == ("inf" in value.lower())
                                             and (number == 0 or abs(number) >= sys.float_info.min)) else None


def read_yaml(text: str, where: str = "<experiment>", ros: bool = False):
    """The data of an experiment's YAML ``text`` (aliases and explicit tags refused, nesting at most
    MAX_DEPTH levels, exponent floats read as numbers).

    ``ros``: the text is a parameter file the nodes will read (load_experiment): refuse every value that the
    ROS 2 parameter parser reads differently or refuses (_NoAliasLoader.check_ros), naming its key.
    """
    where = _printable(where)
    if len(text) > MAX_FILE_BYTES:
        raise ConfigError(f"{where}: too large ({len(text)} characters; an experiment is at most "
                          f"{MAX_FILE_BYTES} bytes)")
    deep = _too_deep_flow(text)
    if deep is not None:      # [[[[... (libyaml's time grows with the square of the depth): name the key from
        text = text[:deep + 1]     # the text up to the bracket too deep, which the loader refuses at once
    loader = _NoAliasLoader(text)
    try:
        events = _CParser(text).raw_parse() if _CParser is not None and deep is None else 0   # counted in C
        if events > MAX_EVENTS:
            raise ConfigError(f"more than {MAX_EVENTS} YAML values and collections ({events} parser events); an "
                              "experiment has a few hundred")
        node = loader.get_single_node()
        if node is not None and ros:
            loader.check_ros(node)
        data = loader.construct_document(node) if node is not None else None
    except ConfigError as error:
        raise ConfigError(f"{where}: {_printable(error, 400)}") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        key = _key_name(loader.key_path)
        raise ConfigError(f"{where}: {key + ': ' if key else ''}{line}not valid YAML ({_printable(problem, 200)})") \
            from None
    except RecursionError:
        raise ConfigError(f"{where}: nested too deeply (at most {MAX_DEPTH} levels)") from None
    except (ValueError, OverflowError) as error:     # e.g. an integer of more than 4300 digits
        key = _key_name(loader.key_path)
        raise ConfigError(f"{where}: {key + ': ' if key else ''}cannot read a value "
                          f"({_printable(error, 200)})") from None
    finally:
        loader.dispose()
    if deep is not None:
        raise ConfigError(f"{where}: line {text.count(chr(10)) + 1}: nested deeper than {MAX_DEPTH} levels")
    return data


_QUOTED_OR_COMMENT = re.compile(r'"(?:[^"\\\n]|\\.)*"|\'(?:[^\'\n]|\'\')*\'|(?:^|(?<=\s))#[^\n]*', re.MULTILINE)


def _too_deep_flow(text: str):
    """Where the flow collections ([...], {...}) of ``text`` first nest deeper than MAX_DEPTH (quoted strings
    and comments aside), or None."""
    if text.count("[") + text.count("{") <= MAX_DEPTH:
        return None
    blank = _QUOTED_OR_COMMENT.sub(lambda match: re.sub(r"[^\n]", " ", match.group()), text)
    depth = 0
    for match in re.finditer(r"[\[\]{}]", blank):
        depth += 1 if match.group() in "[{" else -1
        if depth > MAX_DEPTH:
            return match.start()
    return None


def _read_file(path: Path, where: str, limit: int = MAX_FILE_BYTES,
               what: str = "an experiment is a YAML file") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (an experiment's MAX_FILE_BYTES, a part
    program's MAX_PROGRAM_BYTES); FIFOs, devices, sockets and directories are refused before they are
    opened (a FIFO would block, /dev/zero never end)."""
    try:
        info = path.stat()
    except (OSError, ValueError) as error:   # ValueError: a NUL in the path
        raise ConfigError(f"{where}: cannot read ({getattr(error, 'strerror', None) or error})") from None
    kinds = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
             (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))
    for test, kind in kinds:
        if test(info.st_mode):
            raise ConfigError(f"{where}: not a regular file ({kind}); {what}")
    if not stat.S_ISREG(info.st_mode):
        raise ConfigError(f"{where}: not a regular file; {what}")
    if info.st_size > limit:
        raise ConfigError(f"{where}: too large ({info.st_size} bytes; {what.split(' is ')[0]} is at most {limit})")
    try:   # O_NONBLOCK: should the path have become a FIFO since, opening it does not wait for a writer
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as error:
        raise ConfigError(f"{where}: cannot read ({error.strerror})") from None
    with os.fdopen(descriptor, "rb") as stream:
        if not stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
            raise ConfigError(f"{where}: not a regular file; {what}")
        try:
            raw = stream.read(limit + 1)
        except OSError as error:
            raise ConfigError(f"{where}: cannot read ({error.strerror})") from None
    if len(raw) > limit:
        raise ConfigError(f"{where}: too large (more than {limit} bytes)")
    return raw
