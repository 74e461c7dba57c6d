"""Packages whose names load from their modules on first use (PEP 562), so that a
command imports only what it runs: ``--help`` waits for no numpy, a syntax check for no
executor, the plots for no fits."""
from __future__ import annotations

import importlib
import sys


def lazy_attributes(package: str, names: dict[str, str]):
    """(``__getattr__``, ``__dir__``) for ``package``: each of ``names`` (name -> the
    relative module that defines it) imported when first asked for, then kept."""

    def __getattr__(name: str):
        if name in names:
            value = getattr(importlib.import_module(names[name], package), name)
            setattr(sys.modules[package], name, value)
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__
