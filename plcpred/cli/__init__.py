"""The ``plcpred`` command line. Each command is a thin layer over a library call: its
arguments are defined in :mod:`.parser`, its code in one module per command family
(:mod:`.check`, :mod:`.predict`, :mod:`.emulate`, :mod:`.diagnose`, :mod:`.identify`),
imported only when that command runs (:func:`.main.run_command`)."""
from .main import main
from .parser import build_parser

__all__ = ["build_parser", "main"]
