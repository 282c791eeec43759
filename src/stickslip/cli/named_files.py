"""Scenario and system files by name: the command line's arguments that name a file shipped with the package.

The checkout's ``scenarios/*.toml`` and ``systems/*.toml`` are installed with the package as the data-only packages
:data:`SCENARIOS` and :data:`SYSTEMS` (setup.py maps the two folders in), so that ``stickslip run elmer-fig3-v0.1``
and ``stickslip system run chain2-coulomb`` work from any folder. A file's name is its file name without ``.toml``.
An argument that is an existing path is that path, whatever the shipped files are called.
"""

import contextlib
from importlib import resources
from pathlib import Path

from ..core.errors import StickSlipError

#: the package that holds the shipped scenario files (from the checkout's scenarios/)
SCENARIOS = "stickslip.scenario_files"
#: the package that holds the shipped system files (from the checkout's systems/)
SYSTEMS = "stickslip.system_files"
SUFFIX = ".toml"


class UnknownNameError(StickSlipError, FileNotFoundError):
    """An argument is neither an existing path nor the name of a shipped file; the message lists the names."""


def shipped(package):
    """``{name: file}`` of the ``*.toml`` files shipped in ``package`` (:data:`SCENARIOS` or :data:`SYSTEMS`), in
    name order; the files are :class:`importlib.resources.abc.Traversable`."""
    files = [item for item in resources.files(package).iterdir() if item.is_file() and item.name.endswith(SUFFIX)]
    return {item.name.removesuffix(SUFFIX): item for item in sorted(files, key=lambda item: item.name)}


def resolve(argument, package):
    """The file ``argument`` means: itself if that path exists, else the file shipped in ``package`` of that name.

    Raises :class:`UnknownNameError`, naming the argument and listing the shipped names, if it is neither.
    """
    if Path(argument).exists():
        return Path(argument)
    files = shipped(package)
    if argument in files:
        return files[argument]
    kind = "scenario" if package == SCENARIOS else "system"
    raise UnknownNameError(f"{argument}: no such file, nor the name of a {kind} shipped with stickslip "
                           f"(names: {', '.join(files)})")


@contextlib.contextmanager
def local_paths(files):
    """Paths on the file system of ``files`` (paths or traversables) while the ``with`` block runs (a shipped file
    in a zipped install is copied to a temporary file for that time)."""
    with contextlib.ExitStack() as stack:
        yield [file if isinstance(file, Path) else stack.enter_context(resources.as_file(file)) for file in files]
