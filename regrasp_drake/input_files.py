"""Reading the files a user hands to a command, so that bad content is refused
in one line (InputError) before any work, and never hangs nor crashes.

Every YAML or JSON input (object files, scenarios, regrasp libraries, the
data set's and the flight predictor's JSON) is read through `read_text` and
`load_yaml` or `load_json`, which refuse:
  - a path that is not a regular file (a directory, a device, a pipe);
  - more than MAX_FILE_BYTES bytes, a NUL byte, or text that is not UTF-8;
  - nesting deeper than MAX_DEPTH;
  - YAML aliases that would expand the document past MAX_EXPANDED_NODES
    nodes (an "alias bomb"), or refer to themselves;
  - duplicate mapping keys (YAML and JSON keep the last one silently);
  - non-finite numbers (.nan, .inf, NaN, Infinity, 1e999; the refusal names
    the field) and integers of more than MAX_INT_DIGITS digits.
YAML numbers are read in every notation a person writes: `1e5`, `1.0e5`,
`1E-3` are floats (YAML 1.1, which PyYAML follows, reads them as strings).
"""

import json
import math
import os
import re
import stat
from pathlib import Path

import yaml

from regrasp_drake.errors import InputError, field_error, quote

MAX_FILE_BYTES = 16 * 1024 * 1024
MAX_DEPTH = 32
MAX_EXPANDED_NODES = 100_000
MAX_INT_DIGITS = 18


def read_bytes(path, what: str = "file", max_bytes: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of the regular file at path, at most max_bytes; InputError
    naming the path and `what` was expected otherwise."""
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except OSError as e:
        raise InputError(f"{path}: cannot be read ({e.strerror}), "
                         f"expected a {what}") from None
    if not stat.S_ISREG(mode):
        kind = "a directory" if stat.S_ISDIR(mode) else "not a regular file"
        raise InputError(f"{path}: {kind}, expected a {what}")
    try:
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as e:
        raise InputError(f"{path}: cannot be read ({e.strerror}), "
                         f"expected a {what}") from None
    if len(data) > max_bytes:
        raise InputError(f"{path}: larger than {max_bytes} bytes, "
                         f"expected a {what}")
    return data


def read_text(path, what: str = "text file") -> str:
    """The UTF-8 text of the regular file at path (see read_bytes)."""
    data = read_bytes(path, what)
    where = str(path)
    if b"\0" in data:
        line = data[:data.index(b"\0")].count(b"\n") + 1
        raise InputError(f"{where}: line {line}: a NUL byte (binary content), "
                         f"expected a {what}")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data[:e.start].count(b"\n") + 1
        raise InputError(f"{where}: line {line}: byte {data[e.start]:#04x} is "
                         f"not UTF-8 text, expected a {what}") from None


# ---- YAML ------------------------------------------------------------------
class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader with the limits of the module docstring."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        if self._depth > MAX_DEPTH:
            raise _refusal(self.peek_event().start_mark,
                           f"nested deeper than {MAX_DEPTH} levels")
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def compose_document(self):
        node = super().compose_document()
        _check_expansion(node)
        return node

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    duplicate = key in seen
                    seen.add(key)
                except TypeError:  # an unhashable key: refused below
                    continue
                if duplicate:
                    raise _refusal(key_node.start_mark,
                                   f"key {quote(key)} appears twice, expected "
                                   "each key once")
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node):
        digits = re.sub(r"[^0-9a-fA-F]", "", node.value)
        if len(digits) > MAX_INT_DIGITS:
            raise _refusal(node.start_mark, f"got {quote(node.value)}, "
                           f"expected an integer of at most {MAX_INT_DIGITS} "
                           "digits")
        return super().construct_yaml_int(node)


_Loader.add_constructor("tag:yaml.org,2002:int", _Loader.construct_yaml_int)
# YAML 1.2's floats with an exponent: 1e5, 1.0e5, 1E-3, .5e3 (YAML 1.1 needs
# a dot and a signed exponent).
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9][0-9_]*)"
               r"[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


class Tagged(dict):
    """A YAML mapping under a local tag (`!Rpy {deg: [90, 0, 0]}`): how
    Drake's schema types (a rotation, a distribution) are written in model
    directives. `tag` is the tag's name without the `!`."""

    def __init__(self, tag: str, items=()):
        super().__init__(items)
        self.tag = tag


class _TaggedLoader(_Loader):
    """_Loader that also reads local tags on mappings as Tagged."""


def _construct_tagged(loader, suffix, node):
    if not isinstance(node, yaml.MappingNode):
        raise _refusal(node.start_mark, f"tag !{quote(suffix)[1:-1]} on a "
                       "single value or a list, expected it on a mapping")
    return Tagged(suffix, loader.construct_mapping(node, deep=True))


_TaggedLoader.add_multi_constructor("!", _construct_tagged)


class _TaggedDumper(yaml.SafeDumper):
    """PyYAML's safe dumper that writes Tagged mappings with their tag."""


_TaggedDumper.add_representer(
    Tagged, lambda dumper, data: dumper.represent_mapping(f"!{data.tag}",
                                                          dict(data)))


def dump_yaml(data) -> str:
    """`data` as YAML text, Tagged mappings with their tag (parse_yaml reads
    them back with tags=True)."""
    return yaml.dump(data, Dumper=_TaggedDumper, sort_keys=False)


def _refusal(mark, message: str) -> InputError:
    where = f"line {mark.line + 1}: " if mark is not None else ""
    return InputError(where + message)


def _check_expansion(root) -> None:
    """Refuses a node graph whose aliases expand it past MAX_EXPANDED_NODES
    nodes or MAX_DEPTH levels, or refer to an enclosing node."""
    sizes, open_ = {}, set()

    def size(node, depth):
        if depth > MAX_DEPTH:
            raise _refusal(node.start_mark, f"nested deeper than {MAX_DEPTH} "
                           "levels (aliases expanded)")
        if id(node) in sizes:
            return sizes[id(node)]
        if id(node) in open_:
            raise _refusal(node.start_mark, "an alias refers to a node that "
                           "contains it, expected a finite document")
        open_.add(id(node))
        n = 1
        if isinstance(node, yaml.SequenceNode):
            n += sum(size(child, depth + 1) for child in node.value)
        elif isinstance(node, yaml.MappingNode):
            n += sum(size(k, depth + 1) + size(v, depth + 1)
                     for k, v in node.value)
        open_.discard(id(node))
        if n > MAX_EXPANDED_NODES:
            raise _refusal(node.start_mark, f"aliases expand to more than "
                           f"{MAX_EXPANDED_NODES} values, expected a smaller "
                           "document")
        sizes[id(node)] = n
        return n

    if root is not None:
        size(root, 0)


def parse_yaml(text: str, tags: bool = False):
    """The YAML document `text`, parsed within the module's limits;
    InputError (one line, starting with the line number where known).
    tags: read local tags on mappings (Tagged) instead of refusing them."""
    try:
        data = yaml.load(text, Loader=_TaggedLoader if tags else _Loader)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        where = (f" at line {mark.line + 1}, column {mark.column + 1}"
                 if mark is not None else "")
        problem = e.problem or e.context or "malformed"
        raise InputError(f"not valid YAML{where}: {quote(problem)[1:-1]}") \
            from None
    except yaml.YAMLError as e:
        raise InputError(f"not valid YAML ({quote(str(e))})") from None
    except RecursionError:
        raise InputError(f"nested deeper than {MAX_DEPTH} levels") from None
    check_finite(data)
    return data


def load_yaml(path, what: str = "YAML file", tags: bool = False):
    """The YAML file at path, read (read_text) and parsed (parse_yaml);
    InputError naming the path."""
    return _load(path, what, lambda text: parse_yaml(text, tags=tags))


def _load(path, what: str, parse):
    text = read_text(path, what)
    try:
        return parse(text)
    except InputError as e:
        raise InputError(f"{path}: {e}") from None


# ---- JSON ------------------------------------------------------------------
def _json_pairs(pairs):
    keys = [k for k, _ in pairs]
    if len(set(keys)) != len(keys):
        duplicate = next(k for k in keys if keys.count(k) > 1)
        raise ValueError(f"key {quote(duplicate)} appears twice, expected "
                         "each key once")
    return dict(pairs)


def _json_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise ValueError(f"got {quote(text)}, expected an integer of at most "
                         f"{MAX_INT_DIGITS} digits")
    return int(text)


def parse_json(text: str):
    """The JSON document `text` within the module's limits; InputError."""
    try:
        data = json.loads(text, object_pairs_hook=_json_pairs,
                          parse_int=_json_int)
    except json.JSONDecodeError as e:
        raise InputError(f"line {e.lineno}: not valid JSON ({e.msg})") from None
    except ValueError as e:
        raise InputError(f"{e}") from None
    except RecursionError:
        raise InputError(f"nested deeper than {MAX_DEPTH} levels") from None
    if depth(data) > MAX_DEPTH:
        raise InputError(f"nested deeper than {MAX_DEPTH} levels")
    check_finite(data)
    return data


def load_json(path, what: str = "JSON file"):
    """The JSON file at path, read (read_text) and parsed (parse_json);
    InputError naming the path."""
    return _load(path, what, parse_json)


def check_format(data, path, expected: str, hint: str = "") -> None:
    """Refuses a parsed file that is not a mapping tagged `format:
    expected` (InputError naming the file's format field; hint, e.g. how
    to make the file again, follows what was expected)."""
    if not isinstance(data, dict) or data.get("format") != expected:
        raise field_error(f"{path}: format",
                          data.get("format") if isinstance(data, dict) else data,
                          f"{expected!r}{hint}")


def load_tagged_json(path, what: str, expected: str, command: str) -> dict:
    """The JSON file at path that `command` writes, tagged `format:
    expected` (check_format); InputError naming the file when it is
    missing, unreadable or not one."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such {what} (run `{command}` first)")
    data = load_json(path, f"{what} (JSON)")
    check_format(data, path, expected, f" (run `{command}` again)")
    return data


def check_finite(value, field: str = "") -> None:
    """Refuses a non-finite number anywhere in parsed `value` (InputError
    naming its field, dotted from the top)."""
    if isinstance(value, float) and not math.isfinite(value):
        raise field_error(field or "the document", value, "a finite number")
    if isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            check_finite(item, f"{field}[{i}]")
    elif isinstance(value, dict):
        for key, item in value.items():
            shown = key if isinstance(key, str) and len(key) <= 64 else quote(key)
            check_finite(item, f"{field}.{shown}" if field else str(shown))


def depth(value) -> int:
    """How deeply lists and mappings nest in `value` (a scalar is 0)."""
    if isinstance(value, dict):
        return 1 + max(map(depth, value.values()), default=0)
    if isinstance(value, (list, tuple)):
        return 1 + max(map(depth, value), default=0)
    return 0
