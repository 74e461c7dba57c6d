"""What a project or a library leaves for the check to name (a library the project
references, a file its .plcproj lists that is not there, a library file that could not
be read), kept in ``Program.pragmas`` as ``{TAG text}`` with the position it concerns."""
from __future__ import annotations

from . import ir

_REFERENCE = "library-reference"   # a library the project references
_UNREAD = "library-unread"         # a library file that could not be read, and why
_MISSING = "project-missing"       # a file the .plcproj lists that is not there


def _note(tag: str, text: str) -> str:
    return f"{{{tag} {text}}}"


def _noted(tag: str, programs) -> list[tuple[str, ir.Pos]]:
    """(text, position) of every note ``tag`` among ``programs``' pragmas."""
    head = "{" + tag + " "
    return [(p[len(head):-1], pos) for prog in programs for p, pos in prog.pragmas
            if p.startswith(head)]


def reference_pragma(namespace: str) -> str:
    """How a project records a library it references."""
    return _note(_REFERENCE, namespace)


def referenced_libraries(programs) -> list[str]:
    """The libraries the projects among ``programs`` reference."""
    return [text for text, _ in _noted(_REFERENCE, programs)]


def missing_pragma(include: str) -> str:
    """How a project records a file its .plcproj lists that is not there (the pragma's
    position is the .plcproj's Compile item)."""
    return _note(_MISSING, include)


def missing_project_files(programs) -> list[tuple[str, ir.Pos]]:
    """(file, where the .plcproj lists it) of what the projects among ``programs`` list
    but do not have."""
    return _noted(_MISSING, programs)


def unread_pragma(why: str) -> str:
    """How a library program records a file of the user's libraries it left out."""
    return _note(_UNREAD, why)


def unread_library_files(programs) -> list[str]:
    """Why files of the user's libraries were left out
    (see :func:`.libraries.user_libraries`)."""
    return [text for text, _ in _noted(_UNREAD, programs)]


