"""A block FMU's state as bytes and back: fixed fields packed with :mod:`struct`, checked as they are unpacked.

The FMU's state is the tuple of ``fmu_src/block_interface.py`` (``ExchangeInterface.fmu_state``): ``(block part,
model-exchange part, *extras)``, the block part ``(parameter pairs, v_drive, F_ext, der(F_ext), start time,
trajectory state or None, inputs pending)``, the model-exchange part ``(block state or None, time, interface)``.
:class:`BlockStateFormat` writes it as these parts, in this order, little-endian, without padding:

1. head: a flag for each of: a trajectory follows, a model-exchange block follows, the host used model exchange,
   each extra (FMI 3: a step was taken), each input pending; then the start time and the model's time (s);
2. the inputs ``v_drive``, ``F_ext``, ``der(F_ext)``;
3. the parameters, one field each, in the FMU's order;
4. if flagged, the trajectory: :data:`.trajectory.STATE_FIELDS`, its segment's kind (0 stuck, 1 harmonic, 2 step:
   :data:`.segments.SEGMENT_CLASSES`), then the segment's ``FIELDS`` (a list of reals last, each as a 2-byte count
   and the reals);
5. if flagged, the model-exchange block: :data:`.exchange.STATE_FIELDS`.

Each field is of a kind of :mod:`.saved_state`: a finite real or one that may be ``inf`` is an 8-byte float, a count
an 8-byte signed integer (>= 0), a flag one byte (0 or 1), a mode a signed byte (-1, 0, 1), a real that may be None
a flag byte (1: given) and an 8-byte float (0 when not given). Unpacking checks every field's kind and then the
values together, with the same checks and messages as a saved state's JSON (StateError or ParameterError naming the
first field out of place or range); bytes that end early or go on after the state are refused too. The header that
says whose state the bytes hold comes before all this (the slaves' ``loader_binding``).

The parts that states of a run share (the parameters, the current segment, the model-exchange block) are packed
once while the states hold the same objects, and unpacked once while the bytes hold the same parts: the same
objects give the same bytes, the same bytes the same checks and objects.
"""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math
import operator
import struct
from typing import Any, Callable, Final

from . import saved_state
from .errors import StateError
from .exchange import STATE_FIELDS as EXCHANGE_FIELDS, ExchangeBlock
from .model import check_input, inputs_within_scales
from .segments import SEGMENT_CLASSES, checked_segment
from .trajectory import SEGMENT_PLACE, STATE_FIELDS as TRAJECTORY_FIELDS, STATE_PLACES, checked_state, state_fields

# the kinds of field, as codes (Final: compiled code compares them natively), and their struct formats
_REAL: Final = 0
_TIME_END: Final = 1
_COUNT: Final = 2
_FLAG: Final = 3
_MODE: Final = 4
_OPTIONAL_REAL: Final = 5
_OPTIONAL_STEP: Final = 6
_INF: Final = math.inf
_CODES = {saved_state.REAL: (_REAL, "d"), saved_state.TIME_END: (_TIME_END, "d"), saved_state.COUNT: (_COUNT, "q"),
          saved_state.FLAG: (_FLAG, "B"), saved_state.MODE: (_MODE, "b"),
          saved_state.OPTIONAL_REAL: (_OPTIONAL_REAL, "Bd"), saved_state.OPTIONAL_STEP: (_OPTIONAL_STEP, "Bd")}
_COUNT_OF_REALS = struct.Struct("<H")  # how many reals a list holds
_SEGMENT_PLACE: Final = SEGMENT_PLACE  # where a Trajectory.state holds its segment (Final: a native constant here)
_SEGMENT_CODES = {segment_class.KIND: code for code, segment_class in enumerate(SEGMENT_CLASSES)}
# the C loader's codes of the kinds of field (BlockStateFormat.loader_plan)
_PLAN_CODES = {saved_state.REAL: "d", saved_state.TIME_END: "e", saved_state.COUNT: "q", saved_state.FLAG: "B",
               saved_state.MODE: "b", saved_state.OPTIONAL_REAL: "o", saved_state.OPTIONAL_STEP: "s"}


class Fields:
    """A row of fields ``(name, kind)`` of :mod:`.saved_state`'s kinds (no lists), packed as one struct."""

    names: tuple
    kinds: tuple
    codes: list[int]
    optional: list[int]  # the indexes of the fields that may be None, last first
    layout: struct.Struct
    size: int

    def __init__(self, fields: tuple, prefix: str = "") -> None:
        self.names = tuple(prefix + name for name, _ in fields)
        self.kinds = tuple(kind for _, kind in fields)
        self.codes = [_CODES[kind][0] for kind in self.kinds]
        self.optional = [i for i, code in enumerate(self.codes) if code >= _OPTIONAL_REAL][::-1]
        self.layout = struct.Struct("<" + "".join(_CODES[kind][1] for kind in self.kinds))
        self.size = self.layout.size

    def pack(self, values: Any) -> bytes:
        """The bytes of ``values``, one for each field, in their order."""
        if not self.optional:
            return self.layout.pack(*values)
        flat = list(values)
        for i in self.optional:
            value = flat[i]
            flat[i:i + 1] = (False, 0.0) if value is None else (True, value)
        return self.layout.pack(*flat)

    def unpack(self, data: bytes, offset: int) -> list:
        """The values of the fields packed at ``offset`` of ``data``, each checked and converted to its kind (a flag
        to a bool, a real not given to None): StateError naming the first that is not of its kind, in the words of
        :func:`.saved_state.field`."""
        if offset + self.size > len(data):
            raise StateError(f"the {len(data)} bytes are not a serialized FMU state of this FMU: they end within "
                             f"its fields {self.names[0]} to {self.names[-1]} (bytes {offset} to {offset + self.size})")
        raw = self.layout.unpack_from(data, offset)
        values: list = []
        j = 0
        for i, code in enumerate(self.codes):
            value: object = raw[j]
            j += 1
            if code == _REAL or code == _TIME_END:
                real: float = raw[j - 1]
                ok = real - real == 0.0 or (code == _TIME_END and real == _INF)
            elif code == _COUNT or code == _FLAG or code == _MODE:
                number: int = raw[j - 1]
                ok = number >= 0 if code == _COUNT else (0 <= number <= 1 if code == _FLAG else -1 <= number <= 1)
                if code == _FLAG and ok:
                    value = number == 1
            else:
                value = self._optional(i, raw[j - 1], raw[j])
                j += 1
                ok = value is None or code == _OPTIONAL_REAL or value > 0.0
            if not ok:
                raise StateError(f"saved state {self.names[i]} = {value!r} is not {self.kinds[i]}")
            values.append(value)
        return values

    def places(self, prefix: str, offset: int) -> list[tuple[str, int, str]]:
        """``(prefix + name, offset, struct format)`` of each field packed at ``offset``
        (:meth:`BlockStateFormat.fields`)."""
        places = []
        for name, kind in zip(self.names, self.kinds):
            code = _CODES[kind][1]
            places.append((prefix + name, offset, code))
            offset += struct.calcsize("<" + code)
        return places

    def _optional(self, index: int, given: int, real: float) -> float | None:
        """A real that may be None, packed as ``given`` and ``real``: None, or the real if finite."""
        if given > 1 or (not given and real != 0.0) or (given and not real - real == 0.0):
            what = "a flag" if given > 1 else "not given" if not given else "given"
            raise StateError(f"saved state {self.names[index]} = {real!r} ({what}: {given}) is not "
                             f"{self.kinds[index]}")
        return real if given else None


class _SegmentFields:
    """A kind of segment's fields: its fixed fields as :class:`Fields`, each list of reals after them."""

    def __init__(self, segment_class: Any) -> None:
        self.segment_class = segment_class
        prefix = f"segment ({segment_class.KIND})."
        fields = segment_class.FIELDS
        self.lists = [i for i, (_, kind) in enumerate(fields) if kind == saved_state.REALS]
        self.list_names = [prefix + fields[i][0] for i in self.lists]
        fixed = [i for i in range(len(fields)) if i not in self.lists]
        self.fixed = Fields(tuple(fields[i] for i in fixed), prefix)
        self.pick_fixed = operator.itemgetter(*[i + 1 for i in fixed])  # from to_list(), whose kind is first
        self.reals: dict[int, struct.Struct] = {}  # count -> the struct of that many reals

    def _struct(self, count: int) -> struct.Struct:
        layout = self.reals.get(count)
        if layout is None:
            layout = self.reals[count] = struct.Struct(f"<H{count}d")
        return layout

    def pack(self, segment: Any) -> list[bytes]:
        """The bytes of ``segment``, in parts."""
        values = segment.to_list()
        parts = [self.fixed.pack(self.pick_fixed(values))]
        for i in self.lists:
            reals = values[i + 1]
            parts.append(self._struct(len(reals)).pack(len(reals), *reals))
        return parts

    def unpack(self, data: bytes, offset: int, params: Any) -> tuple[Any, int]:
        """``(the segment, the offset after it)``, checked (:func:`.segments.checked_segment`)."""
        values = self.fixed.unpack(data, offset)
        offset += self.fixed.size
        for i, name in zip(self.lists, self.list_names):
            layout = self._struct(_COUNT_OF_REALS.unpack_from(data, offset)[0] if offset + 2 <= len(data) else 0)
            if offset + layout.size > len(data):
                raise StateError(f"the {len(data)} bytes are not a serialized FMU state of this FMU: they end within "
                                 f"its {name} (bytes {offset} to {offset + layout.size})")
            reals = list(layout.unpack_from(data, offset))
            del reals[0]
            if not _all_finite(reals):
                saved_state.field(name, reals, saved_state.REALS)
            values.insert(i, reals)
            offset += layout.size
        return checked_segment(self.segment_class, values, params), offset


class BlockStateFormat:
    """The bytes of a block FMU's states (module docstring): :meth:`to_bytes` and :meth:`from_bytes`.

    ``parameters``: the parameters' ``(name, kind)`` in the order of the states' parameter pairs; ``inputs``: the
    names of ``v_drive``, ``F_ext`` and ``der(F_ext)`` as the states' pending inputs name them; ``extras``: the names of
    the flags a state holds after its model-exchange part; ``parameters_of``: the runtime's Parameters of the values
    by name (parameters and inputs), each checked (ParameterError naming one out of range). The bytes start with
    the header ``header_of(identity)`` (``loader_binding.state_header``), the identity being ``identity`` followed by
    the names of every field (:meth:`field_names`); bytes that do not are refused with ``mismatch(data, header)``'s
    reason; a state refused before (a dict, ``{"refused": reason}``) serializes as ``refused`` and its reason.
    """

    def __init__(self, parameters: tuple, inputs: tuple, extras: tuple, parameters_of: Callable[[dict], Any],
                 identity: str, header_of: Callable[[str], bytes], refused: bytes,
                 mismatch: Callable[[bytes, bytes], str]) -> None:
        flags = ("trajectory", "exchange", "interface", *extras, *(f"pending.{name}" for name in inputs))
        self.head = Fields(tuple((name, saved_state.FLAG) for name in flags)
                           + (("start_time", saved_state.REAL), ("time", saved_state.REAL)))
        self.inputs = Fields(tuple((name, saved_state.REAL) for name in inputs))
        self.parameters = Fields(parameters)
        self.trajectory = Fields(TRAJECTORY_FIELDS + (("segment", saved_state.COUNT),))
        self.segments = [_SegmentFields(segment_class) for segment_class in SEGMENT_CLASSES]
        self.exchange = Fields(EXCHANGE_FIELDS)
        self.input_names = inputs
        self.extras = len(extras)
        self.parameters_of = parameters_of
        self.header = header_of(" ".join([identity, *self.field_names()]))
        self.refused, self.mismatch = refused, mismatch
        self._pending: dict[tuple, frozenset] = {}  # pending flags -> the frozenset of their names
        # the parts packed last (by the objects they were packed from, which nothing changes) and unpacked last (by
        # their bytes, and the Parameters they were checked under), which states share while they stay as they are
        self._packed: tuple = (None, b"")  # parameter pairs, their bytes
        self._packed_segment: tuple = (None, [])  # segment, its bytes (parts)
        self._packed_block: tuple = (None, b"")  # model-exchange block's state, its bytes
        self._unpacked: tuple = (b"", None)  # parameters' bytes, (pairs, Parameters)
        self._unpacked_segment: tuple = (-1, None, b"", None)  # segment's kind, Parameters, its bytes, the segment
        self._unpacked_block: tuple = (b"", None, None)  # model-exchange block's bytes, Parameters, its state

    def to_bytes(self, state: Any) -> bytes:
        """The bytes of ``state``: the header, then :meth:`pack`'s parts."""
        if type(state) is dict:
            return self.refused + str(state["refused"]).encode("utf-8")
        parts = self.pack(state)
        parts.insert(0, self.header)
        return b"".join(parts)

    def from_bytes(self, data: Any) -> tuple:
        """The state of :meth:`to_bytes`'s bytes ``data``, every field checked: ValueError if they do not start with
        the header, else StateError or ParameterError naming the first field out of place or range."""
        data = bytes(data)
        if not data.startswith(self.header):
            raise ValueError(f"the {len(data)} bytes are not a serialized FMU state of this FMU: "
                             f"{self.mismatch(data, self.header)}")
        return self.unpack(data, len(self.header))

    def field_names(self) -> list[str]:
        """The names of every field a state may hold, in their order."""
        names = [*self.head.names, *self.inputs.names, *self.parameters.names, *self.trajectory.names]
        for segment in self.segments:
            names += [*segment.fixed.names, *segment.list_names]
        return names + list(self.exchange.names)

    def pack(self, state: tuple) -> list[bytes]:
        """The bytes of ``state``, in parts."""
        (pairs, v_drive, F_ext, rate, start_time, trajectory, pending), (block, time, interface) = state[:2]
        flags = [trajectory is not None, block is not None, interface, *state[2:]]
        flags += [name in pending for name in self.input_names]
        parts = [self.head.pack(flags + [start_time, time]), self.inputs.pack((v_drive, F_ext, rate))]
        if self._packed[0] is not pairs:  # a state's pairs are shared while the parameters stay as they are
            self._packed = (pairs, self.parameters.pack([value for _, value in pairs]))
        parts.append(self._packed[1])
        if trajectory is not None:
            segment = trajectory[_SEGMENT_PLACE]
            code = _SEGMENT_CODES[segment.KIND]
            parts.append(self.trajectory.pack(state_fields(trajectory) + (code,)))
            if self._packed_segment[0] is not segment:  # a segment lasts for one step or many
                self._packed_segment = (segment, self.segments[code].pack(segment))
            parts += self._packed_segment[1]
        if block is not None:
            if self._packed_block[0] is not block:  # the same while the block stays as it is (co-simulation)
                self._packed_block = (block, self.exchange.pack(ExchangeBlock.state_fields(block)))
            parts.append(self._packed_block[1])
        return parts

    def unpack(self, data: bytes, offset: int) -> tuple:
        """The state packed at ``offset`` of ``data``, up to its end, every field checked (StateError or
        ParameterError naming the first out of place or range)."""
        head = self.head.unpack(data, offset)
        offset += self.head.size
        inputs = self.inputs.unpack(data, offset)
        offset += self.inputs.size
        pairs, params = self._parameters(data, offset, inputs)
        offset += self.parameters.size
        trajectory = block = None
        if head[0]:
            values = self.trajectory.unpack(data, offset)
            offset += self.trajectory.size
            code = values.pop()
            if code >= len(self.segments):
                raise StateError(f"saved state segment = {code} is not a kind of segment: allowed is 0 to "
                                 f"{len(self.segments) - 1} ({', '.join(c.KIND for c in SEGMENT_CLASSES)})")
            segment, offset = self._segment(data, offset, code, params)
            self._check_held_inputs(params, inputs[0], inputs[1], inputs[2])
            trajectory = checked_state(params, segment, *values)
        if head[1]:
            block = self._block(data, offset, params)
            offset += self.exchange.size
        if offset != len(data):
            raise StateError(f"the {len(data)} bytes are not a serialized FMU state of this FMU: they go on after "
                             f"the state, which ends at byte {offset}")
        extras = 3 + self.extras
        block_part = (pairs, inputs[0], inputs[1], inputs[2], head[-2], trajectory,
                      self._pending_set(tuple(head[extras:extras + len(self.input_names)])))
        return (block_part, (block, head[-1], head[2])) + tuple(head[3:extras])

    def loader_plan(self) -> tuple:
        """How the FMUs' C loader packs and unpacks the states of this format itself (``fast_path.c``, "FMU states as
        bytes"), giving the bytes and states :meth:`to_bytes` and :meth:`from_bytes` give: ``(header, shapes,
        entries)``. ``shapes``: ``(path, length, shared)`` of each tuple a state is made of, outer ones first; a path
        is the indexes that lead from the state to a value; ``shared``: states of a run share the tuple, taken from
        the last state unpacked here where the bytes of its entries are that state's (the model-exchange part: in
        co-simulation no block, the start time and the interface, the same for every state). ``entries``: one for
        each field or part in the order of the bytes, ``(code, path, argument)``:

        - a field of a kind of :mod:`.saved_state`: ``"d"`` a finite real, ``"e"`` a real that may be ``inf``,
          ``"q"`` a count, ``"B"`` a flag, ``"b"`` a mode, ``"o"`` a real that may be None, ``"s"`` a step that may
          be None (argument 0);
        - ``"n"``: a flag, 1 where the value is not None; ``"m"``: a flag, 1 where the value (a frozenset) holds the
          argument, a name;
        - ``"P"``: a part that states share, of ``argument`` bytes (-1: the rest, but the parts of fixed size after
          it): the parameters, the segment with its kind's code, the model-exchange block. The loader takes such a
          part's bytes, and the objects of bytes it saw before, from the last state packed or unpacked here;
        - ``"["``: the value at path holds the next ``count`` entries, if the flag of entry ``flag`` is 1 (else it
          is None); argument ``(flag, count, build, also)``: ``build(template, *values)`` gives the value from the
          same value of the last state unpacked here and the values of those entries' fields, then those of the
          entries ``also`` (indexes of fields before it) (:meth:`checked_like`), or it is None (the value is the
          part inside)."""
        n_head = len(self.head.names) - 2
        flags: list = [("n", (0, 5), 0), ("n", (1, 0), 0), ("B", (1, 2), 0)]
        flags += [("B", (2 + i,), 0) for i in range(self.extras)]
        flags += [("m", (0, 6), name) for name in self.input_names]
        assert len(flags) == n_head
        entries: list = flags + [("d", (0, 4), 0), ("d", (1, 1), 0)]
        held = tuple(range(len(entries), len(entries) + len(self.input_names)))  # the block's inputs
        entries += [("d", (0, 1 + i), 0) for i in range(len(self.input_names))]
        entries.append(("P", (0, 0), self.parameters.size))
        trajectory: list = [(_PLAN_CODES[kind], (0, 5, *place), 0)
                            for kind, place in zip(self.trajectory.kinds[:-1], STATE_PLACES)]
        entries.append(("[", (0, 5), (0, len(trajectory) + 1, self.checked_like, held)))
        entries += trajectory + [("P", (0, 5, _SEGMENT_PLACE), -1)]
        entries += [("[", (1, 0), (1, 1, None, ())), ("P", (1, 0), self.exchange.size)]
        shapes: tuple = (((), 2 + self.extras, False), ((0,), 7, False), ((1,), 3, True))
        return self.header, shapes, tuple(entries)

    def checked_like(self, template: tuple, t, v_drive, F_ext, F_ext_rate, frame_t, rtol, n_stick, n_slip, n_over,
                     chain, burst_start, burst, t_last_event, h, stiff, votes, n_steps, n_rejected,
                     held_drive: float, held_force: float, held_rate: float) -> tuple:
        """The :meth:`.Trajectory.state` of the values of :data:`.trajectory.STATE_FIELDS` (each of its kind) under
        the parameters and with the segment of the trajectory's state ``template`` (:func:`.trajectory.checked_state`),
        after the block's inputs ``v_drive``, ``F_ext`` and ``der(F_ext)`` (``held_*``, :meth:`loader_plan`'s
        ``also``), checked as :meth:`unpack` checks them unless they are the trajectory's, which it checks."""
        params = template[1]
        same_drive: float = v_drive  # the trajectory's inputs, typed: compared natively
        same_force: float = F_ext
        same_rate: float = F_ext_rate
        if not (held_drive == same_drive and held_force == same_force and held_rate == same_rate):
            self._check_held_inputs(params, held_drive, held_force, held_rate)
        return checked_state(params, template[_SEGMENT_PLACE], t, v_drive, F_ext, F_ext_rate, frame_t, rtol, n_stick,
                             n_slip, n_over, chain, burst_start, burst, t_last_event, h, stiff, votes, n_steps,
                             n_rejected)

    def _check_held_inputs(self, params: Any, v_drive: float, F_ext: float, F_ext_rate: float) -> None:
        """ParameterError naming the first of the block's inputs held by a state with a trajectory, under its
        parameters ``params``, that setting it would refuse (:func:`.model.check_input`: finite, within its force
        scale)."""
        if not inputs_within_scales(v_drive, F_ext, F_ext_rate, params):
            for name, value in zip(self.input_names, (v_drive, F_ext, F_ext_rate)):
                check_input(name, value, params)

    def fields(self, data: bytes) -> list[tuple[str, int, str]]:
        """Where each field of the state in ``data`` (:meth:`to_bytes`'s bytes, header included) lies, as
        ``(name, offset, struct format)``, each name after its part (``head.``, ``inputs.``, ``parameters.``,
        ``trajectory.``, ``exchange.``; a segment's fields are named ``segment (<kind>).<field>``; a list of reals
        gives its count's place with format ``"H"``, then the reals' with ``"<count>d"``): how to read or edit one
        field of a state by hand. Nothing is checked: bytes that end early give the fields
        up to their end."""
        offset = len(self.header)
        places = self.head.places("head.", offset)
        flags = data[offset:offset + 2]
        offset += self.head.size
        for part, fields in (("inputs.", self.inputs), ("parameters.", self.parameters)):
            places += fields.places(part, offset)
            offset += fields.size
        if flags[:1] == b"\x01":
            places += self.trajectory.places("trajectory.", offset)
            offset += self.trajectory.size
            code = struct.unpack_from("<q", data, offset - 8)[0] if offset <= len(data) else 0
            segment = self.segments[min(max(code, 0), len(self.segments) - 1)]
            places += segment.fixed.places("", offset)
            offset += segment.fixed.size
            for name in segment.list_names:
                count = _COUNT_OF_REALS.unpack_from(data, offset)[0] if offset + 2 <= len(data) else 0
                places += [(name, offset, "H"), (name, offset + 2, f"{count}d")]
                offset += 2 + 8 * count
        if flags[1:2] == b"\x01":
            places += self.exchange.places("exchange.", offset)
        return [place for place in places if place[1] + struct.calcsize("<" + place[2]) <= len(data)]

    def _parameters(self, data: bytes, offset: int, inputs: list) -> tuple:
        """``(parameter pairs, Parameters)`` of the parameters packed at ``offset``: the same objects for the same
        bytes as the last time (their values, checked then, are the same)."""
        packed = data[offset:offset + self.parameters.size]
        if packed == self._unpacked[0]:
            return self._unpacked[1]
        values = self.parameters.unpack(data, offset)
        pairs = tuple(zip(self.parameters.names, values))
        params = self.parameters_of({**dict(pairs), **dict(zip(self.input_names, inputs))})
        self._unpacked = (packed, (pairs, params))
        return pairs, params

    def _segment(self, data: bytes, offset: int, code: int, params: Any) -> tuple[Any, int]:
        """``(the segment of kind code packed at offset, checked under params, the offset after it)``: the same
        segment (which nothing changes) for the same bytes, kind and Parameters as the last time."""
        kind, checked_under, packed, segment = self._unpacked_segment
        if code == kind and params is checked_under and data.startswith(packed, offset):
            return segment, offset + len(packed)
        segment, end = self.segments[code].unpack(data, offset, params)
        self._unpacked_segment = (code, params, data[offset:end], segment)
        return segment, end

    def _block(self, data: bytes, offset: int, params: Any) -> dict:
        """The model-exchange block's state packed at ``offset``, checked under ``params``: the same dict (which
        nothing changes) for the same bytes and Parameters as the last time."""
        packed = data[offset:offset + self.exchange.size]
        if packed == self._unpacked_block[0] and params is self._unpacked_block[1]:
            return self._unpacked_block[2]
        block = ExchangeBlock.checked_state(params, self.exchange.unpack(data, offset))
        self._unpacked_block = (packed, params, block)
        return block

    def _pending_set(self, flags: tuple) -> frozenset:
        pending = self._pending.get(flags)
        if pending is None:
            pending = self._pending[flags] = frozenset(name for name, flag in zip(self.input_names, flags) if flag)
        return pending


def _all_finite(reals: list) -> bool:
    """Whether ``reals`` (floats) is not empty and holds no infinity or NaN."""
    for value in reals:
        real: float = value
        if not real - real == 0.0:
            return False
    return len(reals) > 0
