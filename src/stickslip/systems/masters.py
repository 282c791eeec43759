"""The masters by name (``--master``): each a module with one class (:mod:`.master` says what it implements)."""

from ..hosts.fmpy_host import FMUError
from .adaptive import AdaptiveMaster
from .master import Master
from .me import MeMaster
from .native import NativeMaster
from .zoh import ZohMaster

#: master name: its class
MASTERS: dict[str, type[Master]] = {cls.NAME: cls for cls in (ZohMaster, MeMaster, AdaptiveMaster, NativeMaster)}


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
