"""Properties of the simulated USB-6001 beyond its AI tasks: device capabilities a script reads,
AO / DIO / counter channels, output buffer, start trigger, and the task properties of tasks
that are not AI (docs/decisions/0290). Rows join :meth:`Usb6001Servicer._properties`.

Device values (UNVERIFIED where marked; NI USB-6001/6002/6003 User Guide and spec sheet):
product number 0x7AD1 (UNVERIFIED: NI's PCI/USB product id of the 6001 was not found), AI
minimum rate 0.1 S/s (UNVERIFIED), AO ranges [-10, 10] V, AO rates 0.1 .. 5000 S/s
(UNVERIFIED), finite and continuous sample modes for AI and AO (no hardware-timed single point),
start triggers only (digital), 16-bit raw samples, ctr0 32 bits, edge counting only.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from nidaqmx.constants import (
    AcquisitionType,
    ChannelType,
    TerminalConfiguration,
    UsageTypeAO,
    UsageTypeCI,
)

from gelrig.simulators.usb6001 import ao as ao_mod
from gelrig.simulators.usb6001 import counter as ctr
from gelrig.simulators.usb6001 import dio, tdms_log
from gelrig.simulators.usb6001 import triggers as trg
from gelrig.simulators.usb6001.device import (
    CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING,
    INVALID_ATTRIBUTE_VALUE,
    MIN_NOT_LESS_THAN_MAX,
    VOLTS,
    DaqmxError,
)
from gelrig.simulators.usb6001.subsystems import IoTask

if TYPE_CHECKING:
    from gelrig.simulators.usb6001.servicer import Prop, Usb6001Servicer

#: NI product id reported for the USB-6001 (UNVERIFIED)
PRODUCT_NUM = 0x7AD1
AI_MIN_RATE = 0.1  # UNVERIFIED
RAW_WIDTH_BYTES = 2
TRIGGER_USAGE_START = 8  # nidaqmx.constants._TriggerUsageTypes.START (a bitfield)
SAMPLE_CLOCK_TIMING, ON_DEMAND_TIMING = 10388, 10390
RESOLUTION_BITS = 10109
MODES = [AcquisitionType.FINITE.value, AcquisitionType.CONTINUOUS.value]
CHAN_TYPE = {"AO": ChannelType.ANALOG_OUTPUT.value, "DI": ChannelType.DIGITAL_INPUT.value,
             "DO": ChannelType.DIGITAL_OUTPUT.value, "CI": ChannelType.COUNTER_INPUT.value}


def _type_of(task: IoTask) -> str:
    if isinstance(task, ao_mod.AOTask):
        return "AO"
    if isinstance(task, dio.DigitalTask):
        return "DO" if task.output else "DI"
    return "CI"


def _chans(task: IoTask) -> list[Any]:
    if isinstance(task, ctr.CounterTask):
        return [task.channel] if task.channel is not None else []
    return list(task.channels)


def extend(servicer: Usb6001Servicer, table: dict[tuple[str, int], Prop]) -> None:
    """Add the rows of this module to ``table`` and make its task rows answer for io tasks."""
    from gelrig.simulators.usb6001.servicer import Prop

    dev, spec = servicer.device, servicer.device.spec
    name = spec.name

    def io(r: Any) -> IoTask | None:
        return servicer.io.get(r.task.name)

    def need(r: Any, kind: type) -> Any:
        task = io(r)
        if not isinstance(task, kind):
            servicer.device.task(r.task.name)
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Task Name: {r.task.name}\nThe property "
                             "does not apply to the task's channels.")
        return task

    def chans(r: Any, kind: type) -> list[Any]:
        task = io(r)
        have = _chans(task) if task is not None else []
        out = select(have, r.channel)
        if not out or not all(
                isinstance(c, kind) for c in out):
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Channel Name: {r.channel}\nThe property "
                             "does not apply to this channel.")
        return out

    def one(r: Any, kind: type, get: Callable[[Any], Any]) -> Any:
        values = {get(c) for c in chans(r, kind)}
        if len(values) != 1:
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Channels {r.channel} differ.")
        return values.pop()

    def each(kind: type, fn: Callable[[Any, Any], None]) -> Callable[[Any, Any], None]:
        def setter(r: Any, v: Any) -> None:
            for c in chans(r, kind):
                fn(c, v)
        return setter

    def either(key: tuple[str, int], get: Callable[[Any], Any],
               set_: Callable[[Any, Any], None] | None = None) -> None:
        """Row ``key`` answers with ``get``/``set_`` for an io task, as before otherwise."""
        old = table[key]

        def getter(r: Any) -> Any:
            return get(r) if io(r) is not None else old.get(r)

        def setter(r: Any, v: Any) -> None:
            if io(r) is None:
                if old.set is None:
                    raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"{old.name} is read-only.")
                old.set(r, v)
            elif set_ is None:
                raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"{old.name} is read-only.")
            else:
                set_(r, v)

        table[key] = Prop(old.name, old.kind, getter,
                          setter if (old.set is not None or set_ is not None) else None,
                          old.reset)

    # --- AI channel properties the device's own table lacks --------------------------------

    def ai_limit(field: str) -> Callable[[Any, Any], None]:
        def setter(r: Any, v: float) -> None:
            task = servicer.device.task(r.task.name)
            if task.running:
                raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING)
            rng = spec.range_volts
            for c in servicer._channels(task, r.channel):
                lo, hi = (v, c.max_val) if field == "min_val" else (c.min_val, v)
                if not -rng <= v <= rng:
                    raise DaqmxError(INVALID_ATTRIBUTE_VALUE,
                                     f"Property: DAQmx_AI_{'Min' if field == 'min_val' else 'Max'}"
                                     f"\nRequested Value: {v:g}\nMaximum Value: {rng:g}\n"
                                     f"Minimum Value: {-rng:g}\nChannel Name: {c.name}")
                if not lo < hi:
                    raise DaqmxError(MIN_NOT_LESS_THAN_MAX, f"Minimum: {lo}\nMaximum: {hi}")
                setattr(c, field, float(v))
        return setter

    ai_max, ai_min = table[("Chan", 0x17DD)], table[("Chan", 0x17DE)]
    table[("Chan", 0x17DD)] = Prop("AI.Max", "Double", ai_max.get, ai_limit("max_val"))
    table[("Chan", 0x17DE)] = Prop("AI.Min", "Double", ai_min.get, ai_limit("min_val"))
    lsb = spec.lsb

    def ai_chan(r: Any) -> Any:
        return servicer._channels(servicer.device.task(r.task.name), r.channel)

    rows: dict[tuple[str, int], Prop] = {
        # device capabilities
        ("Device", 0x231D): Prop("Dev.ProductNum", "UInt32", lambda r: PRODUCT_NUM),
        ("Device", 0x298E): Prop("Dev.AI.MinRate", "Double", lambda r: AI_MIN_RATE),
        ("Device", 0x299B): Prop("Dev.AO.VoltageRngs", "DoubleArray",
                                 lambda r: [-ao_mod.AO_RANGE, ao_mod.AO_RANGE]),
        ("Device", 0x2997): Prop("Dev.AO.MaxRate", "Double", lambda r: ao_mod.AO_MAX_RATE),
        ("Device", 0x2998): Prop("Dev.AO.MinRate", "Double", lambda r: ao_mod.AO_MIN_RATE),
        ("Device", 0x2FDC): Prop("Dev.AI.SampModes", "Int32Array", lambda r: MODES),
        ("Device", 0x2FDD): Prop("Dev.AO.SampModes", "Int32Array", lambda r: MODES),
        ("Device", 0x2986): Prop("Dev.AI.TrigUsage", "Int32", lambda r: TRIGGER_USAGE_START),
        ("Device", 0x2987): Prop("Dev.AO.TrigUsage", "Int32", lambda r: TRIGGER_USAGE_START),
        ("Device", 0x2985): Prop("Dev.DigTrigSupported", "Bool", lambda r: True),
        ("Device", 0x2984): Prop("Dev.AnlgTrigSupported", "Bool", lambda r: False),
        ("Device", 0x2FD3): Prop("Dev.AO.OutputTypes", "Int32Array",
                                 lambda r: [UsageTypeAO.VOLTAGE.value]),
        ("Device", 0x2FD4): Prop("Dev.CI.MeasTypes", "Int32Array",
                                 lambda r: [UsageTypeCI.COUNT_EDGES.value]),
        ("Device", 0x299F): Prop("Dev.CI.MaxSize", "UInt32", lambda r: ctr.COUNTER_BITS),
        # AI channel
        ("Chan", 0x17E0): Prop("AI.CustomScaleName", "String", lambda r: (ai_chan(r), "")[1]),
        ("Chan", 0x1930): Prop("AI.DevScalingCoeff", "DoubleArray",
                               lambda r: (ai_chan(r), [0.0, lsb])[1]),
        ("Read", 0x217A): Prop("Read.RawDataWidth", "UInt32", lambda r: RAW_WIDTH_BYTES),
        ("Write", 0x217D): Prop("Write.RawDataWidth", "UInt32",
                                lambda r: (need(r, ao_mod.AOTask), RAW_WIDTH_BYTES)[1]),
        # AO channel
        ("Chan", 0x1186): Prop("AO.Max", "Double",
                               lambda r: one(r, ao_mod.AOChannel, lambda c: c.max_val),
                               each(ao_mod.AOChannel, lambda c, v: _ao_limit(c, "max_val", v))),
        ("Chan", 0x1187): Prop("AO.Min", "Double",
                               lambda r: one(r, ao_mod.AOChannel, lambda c: c.min_val),
                               each(ao_mod.AOChannel, lambda c, v: _ao_limit(c, "min_val", v))),
        ("Chan", 0x1108): Prop("AO.OutputType", "Int32", lambda r: one(
            r, ao_mod.AOChannel, lambda c: UsageTypeAO.VOLTAGE.value)),
        ("Chan", 0x1184): Prop("AO.Voltage.Units", "Int32",
                               lambda r: one(r, ao_mod.AOChannel, lambda c: VOLTS)),
        ("Chan", 0x188E): Prop("AO.TermCfg", "Int32", lambda r: one(
            r, ao_mod.AOChannel, lambda c: TerminalConfiguration.RSE.value)),
        ("Chan", 0x182C): Prop("AO.Resolution", "Double",
                               lambda r: one(r, ao_mod.AOChannel, lambda c: float(ao_mod.AO_BITS))),
        ("Chan", 0x182B): Prop("AO.ResolutionUnits", "Int32",
                               lambda r: one(r, ao_mod.AOChannel, lambda c: RESOLUTION_BITS)),
        ("Chan", 0x182E): Prop("AO.DAC.Rng.High", "Double",
                               lambda r: one(r, ao_mod.AOChannel, lambda c: ao_mod.AO_RANGE)),
        ("Chan", 0x182D): Prop("AO.DAC.Rng.Low", "Double",
                               lambda r: one(r, ao_mod.AOChannel, lambda c: -ao_mod.AO_RANGE)),
        ("Chan", 0x183A): Prop("AO.UseOnlyOnBrdMem", "Bool",
                               lambda r: one(r, ao_mod.AOChannel, lambda c: False)),
        # output buffer and stream
        ("Buffer", 0x186D): Prop("Buf.Output.BufSize", "UInt32",
                                 lambda r: need(r, ao_mod.AOTask).buffer_size,
                                 lambda r, v: _buffer(need(r, ao_mod.AOTask), v)),
        ("Buffer", 0x230B): Prop("Buf.Output.OnbrdBufSize", "UInt32",
                                 lambda r: (need(r, ao_mod.AOTask), ao_mod.AO_FIFO)[1]),
        ("Write", 0x1460): Prop("Write.SpaceAvail", "UInt32", lambda r: _space(
            servicer, need(r, ao_mod.AOTask))),
        ("Write", 0x192B): Prop("Write.TotalSampPerChanGenerated", "UInt64", lambda r: min(
            (t := need(r, ao_mod.AOTask)).generated(dev.clock.now()), t.written
            if t.regen == ao_mod.DONT_ALLOW_REGEN else 2**63)),
        ("Write", 0x1458): Prop("Write.CurrWritePos", "UInt64",
                                lambda r: need(r, ao_mod.AOTask).written),
        # digital lines
        ("Chan", 0x2178): Prop("DI.NumLines", "UInt32",
                               lambda r: one(r, dio.DigitalChannel, lambda c: len(c.lines))),
        ("Chan", 0x2179): Prop("DO.NumLines", "UInt32",
                               lambda r: one(r, dio.DigitalChannel, lambda c: len(c.lines))),
        ("Read", 0x217C): Prop("Read.DigitalLines.BytesPerChan", "UInt32",
                               lambda r: need(r, dio.DigitalTask).num_lines),
        ("Write", 0x217F): Prop("Write.DigitalLines.BytesPerChan", "UInt32",
                                lambda r: need(r, dio.DigitalTask).num_lines),
        # counter
        ("Chan", 0x18A0): Prop("CI.MeasType", "Int32", lambda r: one(
            r, ctr.EdgeCountChannel, lambda c: UsageTypeCI.COUNT_EDGES.value)),
        ("Chan", 0x0148): Prop("CI.Count", "UInt32", lambda r: need(r, ctr.CounterTask).count(
            servicer.io.lines, dev.clock.now())),
        ("Chan", 0x18C7): Prop("CI.CountEdges.Term", "String",
                               lambda r: one(r, ctr.EdgeCountChannel, lambda c: f"/{name}/PFI0"),
                               each(ctr.EdgeCountChannel, lambda c, v: setattr(
                                   c, "terminal", ctr.check_terminal(v, name)))),
        ("Chan", 0x0697): Prop("CI.CountEdges.ActiveEdge", "Int32",
                               lambda r: one(r, ctr.EdgeCountChannel, lambda c: c.edge),
                               each(ctr.EdgeCountChannel, lambda c, v: setattr(
                                   c, "edge", ctr.check_edge(v))), ctr.RISING),
        ("Chan", 0x0698): Prop("CI.CountEdges.InitialCnt", "UInt32",
                               lambda r: one(r, ctr.EdgeCountChannel, lambda c: c.initial),
                               each(ctr.EdgeCountChannel, lambda c, v: setattr(
                                   c, "initial", ctr.check_initial(v))), 0),
        ("Chan", 0x0696): Prop("CI.CountEdges.Dir", "Int32",
                               lambda r: one(r, ctr.EdgeCountChannel, lambda c: c.direction),
                               each(ctr.EdgeCountChannel, lambda c, v: setattr(
                                   c, "direction", ctr.check_direction(v))), ctr.COUNT_UP),
        # start / reference trigger
        ("Trig", 0x1393): Prop("StartTrig.Type", "Int32",
                               lambda r: servicer.io.trigger(r.task.name).kind,
                               lambda r, v: _trig_type(servicer, r, v), trg.NO_TRIGGER),
        ("Trig", 0x1407): Prop("DigEdge.StartTrig.Src", "String",
                               lambda r: f"/{name}/{servicer.io.trigger(r.task.name).source}",
                               lambda r, v: setattr(servicer.io.trigger(r.task.name), "source",
                                                    trg.check_source(v, name, output=isinstance(
                                                        io(r), ao_mod.AOTask)))),
        ("Trig", 0x1404): Prop("DigEdge.StartTrig.Edge", "Int32",
                               lambda r: servicer.io.trigger(r.task.name).edge,
                               lambda r, v: setattr(servicer.io.trigger(r.task.name), "edge",
                                                    trg.check_edge(v)), trg.RISING),
        ("Trig", 0x190F): Prop("StartTrig.Retriggerable", "Bool", lambda r: False,
                               lambda r, v: None if not v else _raise(trg.refuse_retrigger()),
                               False),
        ("Trig", 0x1419): Prop("RefTrig.Type", "Int32", lambda r: trg.NO_TRIGGER,
                               lambda r, v: None if v == trg.NO_TRIGGER else _raise(
                                   trg.refuse_reference("SetTrigAttributeInt32")), trg.NO_TRIGGER),
    }
    def log_setup(r: Any) -> Any:
        servicer.device.task(r.task.name)
        return servicer.io.logging.setup(r.task.name)

    rows[("Read", 0x2EC4)] = Prop("Logging.FilePath", "String",
                                  lambda r: ((s := log_setup(r)) and s.path) or "")
    rows[("Read", 0x2EC5)] = Prop("Logging.Mode", "Int32",
                                  lambda r: ((s := log_setup(r)) and s.mode) or tdms_log.OFF)
    rows[("Write", 0x1453)] = Prop("Write.RegenMode", "Int32",
                                   lambda r: need(r, ao_mod.AOTask).regen,
                                   lambda r, v: _regen(need(r, ao_mod.AOTask), v),
                                   ao_mod.ALLOW_REGEN)
    table.update(rows)

    # --- task, channel and timing rows that must answer for io tasks ----------------------

    def names(r: Any) -> str:
        return ", ".join(c.name for c in _chans(io(r)))  # type: ignore[arg-type]

    either(("Task", 0x1273), names)
    either(("Task", 0x2181), lambda r: len(_chans(io(r))))  # type: ignore[arg-type]
    either(("Task", 0x230E), lambda r: name if _chans(io(r)) else "")  # type: ignore[arg-type]
    either(("Task", 0x29BA), lambda r: 1 if _chans(io(r)) else 0)  # type: ignore[arg-type]
    either(("Task", 0x1274), lambda r: servicer.io.is_done(r.task.name))
    either(("Read", 0x1823), names)
    either(("Read", 0x217B), lambda r: len(_chans(io(r))))  # type: ignore[arg-type]
    either(("Read", 0x1223), lambda r: 1)

    def chan_of(r: Any) -> Any:
        return chans(r, object)

    either(("Chan", 0x187F), lambda r: (chan_of(r), CHAN_TYPE[_type_of(io(r))])[1])  # type: ignore[arg-type]
    either(("Chan", 0x18F5), lambda r: ", ".join(_physical(c, name) for c in chan_of(r)))
    def describe(r: Any, v: str) -> None:
        for c in chan_of(r):
            c.description = v

    either(("Chan", 0x1926), lambda r: chan_of(r)[0].description, describe)
    either(("Chan", 0x2304), lambda r: (chan_of(r), False)[1])

    def ao_timing(r: Any, rate: float | None = None, mode: int | None = None,
                  samps: int | None = None) -> None:
        task = io(r)
        if not isinstance(task, ao_mod.AOTask):
            raise dio.refuse_sample_clock(task) if isinstance(task, dio.DigitalTask) else \
                _counter_clock(r.task.name)
        servicer.io.ao.cfg_timing(task, task.rate if rate is None else rate,
                                  task.sample_mode if mode is None else mode,
                                  task.samps_per_chan if samps is None else samps)

    def timing_type(r: Any, v: int) -> None:
        task = io(r)
        if v == ON_DEMAND_TIMING:
            if isinstance(task, ao_mod.AOTask):
                if task.running:
                    raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING)
                task.timing_set = False
            return
        if v != SAMPLE_CLOCK_TIMING:
            raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_SampTimingType\n"
                             f"Requested Value: {v}\nPossible Values: Sample Clock, On Demand")
        ao_timing(r)

    def ao_field(field: str) -> Callable[[Any], Any]:
        def get(r: Any) -> Any:
            task = io(r)
            if isinstance(task, ao_mod.AOTask):
                return getattr(task, field)
            raise dio.refuse_sample_clock(task) if isinstance(task, dio.DigitalTask) else \
                _counter_clock(r.task.name)
        return get

    either(("Timing", 0x1344), ao_field("rate"), lambda r, v: ao_timing(r, rate=v))
    either(("Timing", 0x22C8), lambda r: (ao_field("rate")(r), ao_mod.AO_MAX_RATE)[1])
    either(("Timing", 0x1300), ao_field("sample_mode"), lambda r, v: ao_timing(r, mode=v))
    either(("Timing", 0x1310), ao_field("samps_per_chan"), lambda r, v: ao_timing(r, samps=v))
    either(("Timing", 0x1347), lambda r: SAMPLE_CLOCK_TIMING if isinstance(
        t := io(r), ao_mod.AOTask) and t.timing_set else ON_DEMAND_TIMING, timing_type)


def select(have: list[Any], names: str) -> list[Any]:
    """The channels of ``have`` named in ``names`` (all if empty): a name as given, or a range
    such as ``Dev1/ao0:1`` that nidaqmx makes of a list; [] if any name is not there."""
    from nidaqmx.utils import unflatten_channel_string

    by_name = {c.name.lower(): c for c in have}
    out: list[Any] = []
    for entry in (n.strip() for n in names.split(",")):
        if not entry:
            continue
        if entry.lower() in by_name:
            out.append(by_name[entry.lower()])
            continue
        try:
            parts = unflatten_channel_string(entry)
        except Exception:
            return []
        if not all(p.lower() in by_name for p in parts):
            return []
        out += [by_name[p.lower()] for p in parts]
    return out if names.strip() else list(have)


def _raise(fault: DaqmxError) -> None:
    raise fault


def _physical(chan: Any, device: str) -> str:
    if isinstance(chan, ao_mod.AOChannel):
        return f"{device}/ao{chan.index}"
    if isinstance(chan, dio.DigitalChannel):
        from gelrig.simulators.usb6001.lines import line_name
        return ", ".join(f"{device}/{line_name(i)}" for i in chan.lines)
    return f"{device}/ctr0"


def _counter_clock(task: str) -> DaqmxError:
    return DaqmxError(INVALID_ATTRIBUTE_VALUE, "Property: DAQmx_SampTimingType\nRequested "
                      "Value: Sample Clock\nPossible Values: On Demand\nThe USB-6001's counter "
                      f"is read on demand only (UNVERIFIED).\nTask Name: {task}")


def _ao_limit(chan: ao_mod.AOChannel, field: str, v: float) -> None:
    if abs(v) > ao_mod.AO_RANGE:
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_AO_"
                         f"{'Max' if field == 'max_val' else 'Min'}\nRequested Value: {v:g}\n"
                         f"Maximum Value: {ao_mod.AO_RANGE:g}\nMinimum Value: "
                         f"{-ao_mod.AO_RANGE:g}")
    lo, hi = (v, chan.max_val) if field == "min_val" else (chan.min_val, v)
    if not lo < hi:
        raise DaqmxError(MIN_NOT_LESS_THAN_MAX, f"Minimum: {lo}\nMaximum: {hi}")
    setattr(chan, field, float(v))


def _regen(task: ao_mod.AOTask, v: int) -> None:
    if task.running:
        raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING)
    if v not in (ao_mod.ALLOW_REGEN, ao_mod.DONT_ALLOW_REGEN):
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_Write_RegenMode\n"
                         f"Requested Value: {v}\nPossible Values: Allow Regeneration "
                         f"({ao_mod.ALLOW_REGEN}), Do Not Allow Regeneration "
                         f"({ao_mod.DONT_ALLOW_REGEN})")
    task.regen = v


def _buffer(task: ao_mod.AOTask, v: int) -> None:
    if task.running:
        raise DaqmxError(CAN_NOT_PERFORM_OP_WHILE_TASK_RUNNING)
    if v < 2 and v != 0:
        raise DaqmxError(INVALID_ATTRIBUTE_VALUE, f"Property: DAQmx_Buf_Output_BufSize\n"
                         f"Requested Value: {v}\nMinimum Value: 2")
    task.buffer_request = int(v) if v else None


def _space(servicer: Usb6001Servicer, task: ao_mod.AOTask) -> int:
    size = task.buffer_size
    if not task.running or task.regen == ao_mod.ALLOW_REGEN:
        return max(0, size - task.written) if task.buffer_request is not None or \
            not task.running else 0
    done = task.generated(servicer.device.clock.now())
    return max(0, size - (task.written - done))


def _trig_type(servicer: Usb6001Servicer, r: Any, v: int) -> None:
    trig = servicer.io.trigger(r.task.name)
    trig.kind = trg.check_type(v)
    if servicer.io.get(r.task.name) is None:
        servicer.io.arm_ai(r.task.name)
