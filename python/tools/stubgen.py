# SPDX-License-Identifier: BSD-3-Clause
"""mypy's stubgen, run on the built extension with two additions: its docstring parser
takes the bare ``*`` that pybind11 writes before keyword-only arguments (py::kw_only()),
and static methods (py::def_static) get their signatures and ``@staticmethod``.

stubgen reads a C extension's signatures from the first line of each docstring, and the
parser of mypy 1.0 (Debian's) takes ``*`` for a malformed argument name: it then drops the
whole signature and writes ``(*args, **kwargs)``, so the stubs lose every parameter of a
constructor such as ``SACMultiPlaneSegmentation(*, distance_threshold_m: float = 0.05,
...)``. Accepting ``*`` as an argument makes stubgen write it back as the keyword-only
marker. A stubgen whose parser has no such pattern is run unchanged.

mypy 1.0 takes a class's ``staticmethod`` objects for methods and reads the signature
from the staticmethod's own docstring (Python's ``staticmethod(function) -> method``),
so ``PlanarGridMap.load`` became ``def load(self, *args, **kwargs) -> Any`` and mypy
refused ``PlanarGridMap.load(path)``. Here the wrapped function's signatures are written
as a function's, each marked ``@staticmethod``.

stubgen also takes any ``name(...)`` in a docstring's prose for one more signature
(``with mapper.read_map() as m:`` gave ``def read_map(self) -> Any`` beside the real
one, under ``@overload``). Of the signatures a docstring gives, those with neither a
typed argument nor a return type are dropped when a typed one exists, and repeated ones
once; pybind11 writes every real signature typed.

A property's type is read from its docstring before its getter's signature, and the
prose of a docstring such as ``Mapper.map``'s (``... read_map() ...``) or
``Cuboids.normals``' (``unit face normals (toward ...``) reads as a signature returning
``Any``: a property whose getter has pybind11's signature line is typed by that line,
unless that says only ``object``.

An exception type made with PyErr_NewException has no place for its attributes'
types: the module gives them as the type's ``__annotations__`` (``ConfigError``'s
``file``, ``line`` and ``column``), and they are declared in the class's stub.

pybind11 writes an array parameter as ``numpy.ndarray[numpy.float32]`` (its C++ type),
but every array parameter of the module converts what numpy can (lists included:
py::array::forcecast), so such parameters become ``numpy.typing.ArrayLike`` in the
written stubs; return types stay arrays.

Usage: python3 stubgen.py <stubgen arguments>
"""
import os
import re
import sys

import mypy.stubdoc
import mypy.stubgenc
from mypy.stubgen import main

_name = getattr(mypy.stubdoc, "_ARG_NAME_RE", None)
if _name is not None and not _name.match("*"):
    mypy.stubdoc._ARG_NAME_RE = re.compile(_name.pattern + r"|\*$")

_function_stub = getattr(mypy.stubgenc, "generate_c_function_stub", None)


def _static_aware_function_stub(module, name, obj, output, imports, sig_generators,
                                self_var=None, class_name=None):
    if not isinstance(obj, staticmethod):
        _function_stub(module, name, obj, output, imports, sig_generators,
                       self_var=self_var, class_name=class_name)
        return
    lines = []
    _function_stub(module, name, obj.__func__, lines, imports, sig_generators)
    for line in lines:
        if line.startswith("def "):
            output.append("@staticmethod")
        output.append(line)


if _function_stub is not None:
    mypy.stubgenc.generate_c_function_stub = _static_aware_function_stub

_property_stub = getattr(mypy.stubgenc, "generate_c_property_stub", None)
# a getter's pybind11 signature line with a return type other than ``object`` (a
# py::object, e.g. a map or None, stays as the docstring gives it)
_GETTER_SIGNATURE = re.compile(r"^\(.*\) -> (?!object\s*$)\S", re.MULTILINE)


class _TypedByGetter:
    """A property seen through its getter alone (no docstring of its own)."""

    __doc__ = None

    def __init__(self, prop):
        self.fget = prop.fget


def _getter_typed_property_stub(name, obj, *args, **kwargs):
    fget = getattr(obj, "fget", None)
    if (type(obj).__name__ != "pybind11_static_property" and fget is not None
            and _GETTER_SIGNATURE.match(getattr(fget, "__doc__", None) or "")):
        obj = _TypedByGetter(obj)
    _property_stub(name, obj, *args, **kwargs)


if _property_stub is not None:
    mypy.stubgenc.generate_c_property_stub = _getter_typed_property_stub

_docstring_sig = getattr(mypy.stubgenc, "DocstringSignatureGenerator", None)


def _typed(sig):
    return sig.ret_type != "Any" or any(arg.type for arg in sig.args)


def _real_signatures(self, func, module_name, name):
    sigs = _docstring_function_sig(self, func, module_name, name)
    if not sigs or len(sigs) < 2:
        return sigs
    kept = [sig for sig in sigs if _typed(sig)] or sigs[:1]
    out, seen = [], set()
    for sig in kept:
        key = (tuple((a.name, a.type, a.default) for a in sig.args), sig.ret_type)
        if key not in seen:
            seen.add(key)
            out.append(sig)
    return out


if _docstring_sig is not None:
    _docstring_function_sig = _docstring_sig.get_function_sig
    _docstring_sig.get_function_sig = _real_signatures

_ARRAY_PARAMETER = re.compile(r"(\w+: )numpy\.ndarray\[numpy\.(?:float32|float64|int64)\]")


def _array_like_parameters(path):
    """Rewrites the array parameters of the stub file at path as ArrayLike."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    out = []
    for line in lines:
        if line.lstrip().startswith("def ") and ") ->" in line:
            parameters, returns = line.rsplit(") ->", 1)
            line = _ARRAY_PARAMETER.sub(r"\1numpy.typing.ArrayLike", parameters) + ") ->" + returns
        out.append(line)
        if line == "import numpy":
            out.append("import numpy.typing")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(out))


def _declare_annotated_attributes(path, module_name):
    """Declares the attributes of the module's classes that carry ``__annotations__``
    (their types as strings) in the classes' stubs, in place of the ``__annotations__``
    class variable stubgen writes for them."""
    import importlib
    module = importlib.import_module(module_name)
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    out = []
    declared = False
    for line in lines:
        match = re.match(r"class (\w+)\((.*)\):( \.\.\.)?$", line)
        if match:
            annotations = getattr(getattr(module, match.group(1), None),
                                  "__annotations__", None)
            declared = isinstance(annotations, dict) and bool(annotations)
            if declared:
                out.append(f"class {match.group(1)}({match.group(2)}):")
                out.extend(f"    {name}: {kind}" for name, kind in annotations.items())
                continue
        elif declared and line.strip().startswith("__annotations__:"):
            continue
        out.append(line)
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(out))


def _written_stub(argv):
    """The module and the stub file stubgen writes for `-m MODULE -o DIR`, or None."""
    try:
        module = argv[argv.index("-m") + 1]
        folder = argv[argv.index("-o") + 1]
    except (ValueError, IndexError):
        return None
    return module, os.path.join(folder, *module.split(".")) + ".pyi"


if __name__ == "__main__":
    status = main()
    written = _written_stub(sys.argv)
    if not status and written and os.path.exists(written[1]):
        _array_like_parameters(written[1])
        _declare_annotated_attributes(written[1], written[0])
    sys.exit(status)
