"""The masters by name (``--master``): each a module with one class (:mod:`.master` says what it implements)."""

import importlib
from collections.abc import Mapping

from ..hosts.fmpy_host import FMUError
from .master import Master


class _Classes(Mapping):
    """Name: class, each class's module imported when the class is first asked for (a run loads only its master's,
    not e.g. the ``zoh`` master's SSP engines and the FMU builds behind them)."""

    def __init__(self, homes):
        self._homes = homes  # name: (module, class name)

    def __getitem__(self, name):
        module, cls = self._homes[name]
        return getattr(importlib.import_module(module, __package__), cls)

    def __iter__(self):
        return iter(self._homes)

    def __len__(self):
        return len(self._homes)


#: master name: its class
MASTERS: Mapping[str, type[Master]] = _Classes({"zoh": (".zoh", "ZohMaster"), "me": (".me", "MeMaster"),
                                                "adaptive": (".adaptive", "AdaptiveMaster"),
                                                "native": (".native", "NativeMaster")})


def make_master(name, **options) -> Master:
    """The master ``name`` with ``options`` (None values are left out: the master's defaults); FMUError for an
    unknown master or an option it does not take."""
    if name not in MASTERS:
        raise FMUError(f"master {name!r}: allowed are {sorted(MASTERS)}")
    cls = MASTERS[name]
    given = {key: value for key, value in options.items() if value is not None}
    wrong = sorted(set(given) - set(cls.OPTIONS))
    if wrong:
        takers = {key: sorted(n for n, c in MASTERS.items() if key in c.OPTIONS) for key in wrong}
        raise FMUError(f"master {name!r} takes no option {wrong[0]!r} (the masters {takers[wrong[0]]} do)")
    return cls(**given)
