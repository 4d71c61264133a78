"""A case's runs as a case file shapes them: a group's keyframed signals and offsets (each
signal, or each of its labels, given once, at times that increase), its collisions with a part
and a level, and whether its chain is left unfinished (:func:`read_run_group`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from idefix_rules import signals
from idefix_rules.campaign.input.yamlsource import Loc, flag_value
from idefix_rules.rulebook.infer import did_you_mean
from idefix_rules.testing.case_model import SHAPEABLE, Collision, Keyframes, RunGroup
from idefix_rules.testing.case_reader import CaseReader
from idefix_rules.units import TIME

_COLLISION_KEYS = ("part", "level", "from", "to", "at", "buffer")


def read_run_group(reader: CaseReader, data: Mapping[str, Any], loc: Loc, count: int) -> RunGroup:
    keyframes: tuple[Keyframes, ...] = ()
    if "signals" in data:
        keyframes += read_keyframe_block(reader, data["signals"], (*loc, "signals"), False)
    if "offsets" in data:
        keyframes += read_keyframe_block(reader, data["offsets"], (*loc, "offsets"), True)
    collisions: list[Collision] = []
    if "collisions" in data:
        items = data["collisions"]
        if not isinstance(items, list):
            reader.fail("T010", "'collisions' must be a list", (*loc, "collisions"))
            items = []
        for number, item in enumerate(items):
            found = _collision(reader, item, (*loc, "collisions", number))
            if found is not None:
                collisions.append(found)
    unfinished = False
    if "unfinished" in data:
        if isinstance(flag_value(data["unfinished"]), bool):
            unfinished = bool(flag_value(data["unfinished"]))
        else:
            reader.fail("T012", "'unfinished' is true or false", (*loc, "unfinished"))
    return RunGroup(count, keyframes, tuple(collisions), unfinished)


def _signal_key(reader: CaseReader, key: str, loc: Loc) -> tuple[str, str | None] | None:
    name, label = key, None
    if key.endswith("]") and "[" in key:
        name, _, rest = key.partition("[")
        label = rest[:-1].strip()
        name = name.strip()
    spec = signals.lookup(name)
    if spec is None or (name not in SHAPEABLE and signals.area_signal(name) is None):
        why = ("is computed from the others" if spec is not None and spec.kind == "derived"
               else "follows the chain" if name == "command"
               else "follows the chain's commands (a run whose chain does not finish: "
                    "'unfinished: true')" if name == "done"
               else "is given by 'collisions'" if name.startswith("collision.")
               else "is not a signal")
        reader.fail("T004", f"{name!r} cannot be shaped by a case: it {why}", loc,
                    did_you_mean(name, list(SHAPEABLE)) or f"signals: {', '.join(SHAPEABLE)}",
                    at_key=True)
        return None
    area = signals.area_signal(name)
    if area is not None and reader.areas is not None and area[0] not in reader.areas:
        # a typo, or an area of another rulebook: its keyframes would be read by no rule
        reader.fail("T004", f"{name!r} cannot be shaped by a case: the rulebook declares no "
                    f"area {area[0]!r}" + (f" (it declares {', '.join(map(repr, reader.areas))})"
                                           if reader.areas else ""), loc,
                    did_you_mean(area[0], list(reader.areas)) if reader.areas else
                    "declare it in the rulebook's obstacles block", at_key=True)
        return None
    if label is not None:
        axis = next((a for a in spec.axes if a != "time"), None)
        labels = signals.AXIS_LABELS.get(axis or "", ())
        if label not in labels:
            reader.fail("T004", f"{name!r} has no label {label!r}" + (
                f"; its labels are {', '.join(labels)}" if labels else " (it has no wheel or "
                "part axis)"), loc, at_key=True)
            return None
    return name, label


def read_keyframe_block(reader: CaseReader, data: Any, loc: Loc, offset: bool
                        ) -> tuple[Keyframes, ...]:
    if not isinstance(data, dict):
        reader.fail("T002", "expected a mapping of signal names to keyframes "
                    "(e.g. 'wheel.slip[FL]: {0 s: 10 %, 20 s: 80 %}')", loc)
        return ()
    out = []
    shaped: dict[tuple[str, str | None], str] = {}  # (signal, label) -> the key that shaped it
    for key, frames in data.items():
        kloc = (*loc, key)
        found = _signal_key(reader, str(key), kloc)
        if found is None:
            continue
        name, label = found
        # the whole signal and one of its labels, or one label written twice ('[FL]', '[ FL ]')
        clash = shaped.get((name, label)) or (
            shaped.get((name, None)) if label is not None else
            next((k for (n, _), k in shaped.items() if n == name), None))
        if clash is not None:
            reader.fail("T006", f"{key!r} shapes what {clash!r} already shapes; each signal "
                        "(or each of its labels) is given once", kloc,
                        "give each label its own keyframes, or the whole signal once",
                        at_key=True)
            continue
        shaped[(name, label)] = str(key)
        spec = signals.lookup(name)
        assert spec is not None
        if not isinstance(frames, dict) or not frames:
            if isinstance(frames, str | int | float) and not isinstance(frames, bool):
                frames = {"0 s": frames}  # a constant value
            else:
                reader.fail("T006", "keyframes are a mapping of times to values, e.g. "
                            "'{0 s: 10 %, 20 s: 80 %}', or one value", kloc)
                continue
        times: list[float] = []
        values: list[float] = []
        for time_text, value in frames.items():
            time = reader.quantity(time_text, kloc, TIME, f"keyframe time {time_text!r}")
            number = reader.quantity(value, (*kloc, time_text), spec.dimension,
                                     f"{key} at {time_text}")
            if time is None or number is None:
                continue
            if time < 0 or (times and time <= times[-1]):
                reader.fail("T006", f"keyframe times must start at 0 s or later and increase; "
                            f"{time_text!r} does not", (*kloc, time_text), at_key=True)
                continue
            times.append(time)
            values.append(number)
        if times:
            out.append(Keyframes(name, label, tuple(times), tuple(values), offset,
                                 reader.span(kloc, at_key=True)))
    return tuple(out)


def _collision(reader: CaseReader, data: Any, loc: Loc) -> Collision | None:
    if not isinstance(data, dict):
        reader.fail("T010", "a collision is a mapping: {part: wheel, level: L2, at: 30 s}", loc)
        return None
    reader.unknown_keys(data, loc, _COLLISION_KEYS)
    parts, levels = signals.AXIS_LABELS["part"], signals.AXIS_LABELS["level"]
    part, level = data.get("part"), data.get("level")
    ok = True
    if part not in parts:
        reader.fail("T010", f"part must be one of {', '.join(parts)}, got {part!r}",
                    (*loc, "part"))
        ok = False
    if level not in levels:
        reader.fail("T010", f"level must be one of {', '.join(levels)}, got {level!r}",
                    (*loc, "level"))
        ok = False
    if "at" in data and ("from" in data or "to" in data):
        reader.fail("T010", "a collision is 'at' one time or 'from' (and 'to') a span, not both",
                    loc)
        return None
    if "to" in data and "from" not in data:
        reader.fail("T010", "'to' needs 'from'", (*loc, "to"), at_key=True)
        return None
    if "at" in data:
        start = end = reader.quantity(data["at"], (*loc, "at"), TIME, "at")
    elif "from" in data:
        start = reader.quantity(data["from"], (*loc, "from"), TIME, "from")
        end = reader.quantity(data.get("to", data["from"]), (*loc, "to"), TIME, "to")
    else:
        reader.fail("T010", "a collision needs 'at' or 'from' (and 'to')", loc)
        return None
    buffer_only = flag_value(data.get("buffer", False))
    if not isinstance(buffer_only, bool):
        reader.fail("T010", "'buffer' is true or false", (*loc, "buffer"))
        ok = False
    if start is None or end is None or not ok:
        return None
    if start < 0:  # before the run: it would count as a hit the run never had
        key = "at" if "at" in data else "from"
        reader.fail("T010", f"a collision {key} {data[key]} lies before the run's start: "
                    "times count from 0 s", (*loc, key))
        return None
    if end < start:
        reader.fail("T010", "'to' comes before 'from'", (*loc, "to"))
        return None
    return Collision(str(part), str(level), start, end, bool(buffer_only),
                     reader.span(loc))
