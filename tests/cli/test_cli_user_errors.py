"""A careless user and a hostile CI against ``idefix-verify``: every mistake exits 2 with a
message naming file, line and column where they are knowable, never a traceback, never lost work.

Each case writes its files into an empty folder, runs the command line in-process from there
and checks the exit code and message fragments. Campaign cases fail before any simulation.
"""

from __future__ import annotations

import importlib
import io
import json
import os
import warnings
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import pytest

from idefix_rules.cli import COMMAND_MODULES, main
from idefix_rules.cli.fmt import formatted_text

RULEBOOK = """\
rulebook "cli-test" version "0.1.0"
purpose "Small rulebook for the command-line tests"

const critical_slip = 70 %
  because "Slip above 70 % is critical"

settings {
  theoretical_slip = 10 %
  tolerance_growth = 5 cm/rad
}

index I_s "wheel slip ratio" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
  because "Slip"
}

verdict acceptable_risk: require risk <= 50 %
  because "Mean risk limit"

rank by risk, time, energy
"""

CAMPAIGN = """\
name: cli
fmu:
  path: toy.fmu
rulebook: test.rules
output: out
runs: 6
workers: 1
uncertainty:
  method: monte_carlo
  seed: 5
  parameters:
    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}
    toy.slip: {distribution: uniform, low: 0.05, high: 0.25}
paths:
  straight:
    - {max_wheel_rate: "0.1 rad/s", delta_position: "0.1 m", delta_heading: "0 deg"}
  arc:
    - {max_wheel_rate: "0.1 rad/s", delta_position: "0.1 m", delta_heading: "20 deg"}
simulation:
  output_interval: "0.5 s"
  extra_time: "2 s"
"""
STRAIGHT = '    - {max_wheel_rate: "0.1 rad/s", delta_position: "0.1 m", delta_heading: "0 deg"}\n'

TURN_RULE = ("command max_turn: require abs(delta_heading) <= 10 deg\n"
             "  because \"Largest allowed turn per command\"\n")

TOY = object()  # placeholder: the toy FMU of the campaign tests
FOLDER = object()  # placeholder: an empty folder
RUN = ("campaign.yaml", "--runs", "2", "--quiet", "--no-report")

Files = dict[str, object]


def campaign(*replacements: tuple[str, str], append: str = "") -> Files:
    """The standard campaign folder, the campaign text edited by ``(old, new)`` pairs."""
    text = CAMPAIGN
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new, 1)
    return {"campaign.yaml": text + append, "test.rules": RULEBOOK, "toy.fmu": TOY}


def with_files(files: Files, **more: object) -> Files:
    return {**files, **{name.replace("__", "."): value for name, value in more.items()}}


def _zip_of(members: dict[str, bytes]) -> bytes:
    """A zip archive of ``members`` (stored, so random bytes keep their size)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def _npy_of_objects() -> bytes:
    import io

    buffer = io.BytesIO()
    np.save(buffer, np.array([{"height": 1.0}], dtype=object), allow_pickle=True)
    return buffer.getvalue()


NPY_OBJECTS = _npy_of_objects()  # a .npy of pickled Python objects: never loaded


def _npz() -> bytes:
    import io

    buffer = io.BytesIO()
    np.savez(buffer, heights=np.zeros((3, 3)))
    return buffer.getvalue()


def _npy(array: np.ndarray) -> bytes:
    import io

    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=False)
    return buffer.getvalue()

TERRAIN_HEADER = "IDEFIX-TERRAIN 1\nnx 3\nny 3\norigin -1.0 -1.0\ncell 1.0\nrocks 0\nheights\n"


def terrain_file(header: str = TERRAIN_HEADER, heights: np.ndarray | None = None,
                 cut: int = 0) -> bytes:
    text = header
    grid = (np.zeros(9) if heights is None else heights).astype("<f8").tobytes()
    return text.encode() + (grid[:-cut] if cut else grid)


def fmu_with_description(description: str) -> Callable[[Path], bytes]:
    """An FMU whose modelDescription.xml is replaced (the rest of the toy FMU kept)."""
    def build(toy: Path) -> bytes:
        target = toy.parent / "variant.fmu"
        with zipfile.ZipFile(toy) as source, zipfile.ZipFile(target, "w") as out:
            for name in source.namelist():
                if name != "modelDescription.xml":
                    out.writestr(name, source.read(name))
            out.writestr("modelDescription.xml", description)
        return target.read_bytes()
    return build


def foreign_hdf5(toy: Path) -> bytes:
    """An HDF5 file some other tool wrote."""
    path = toy.parent / "foreign.h5"
    with h5py.File(path, "w") as file:
        file.create_dataset("temperature", data=[20.5, 21.0])
    return path.read_bytes()


FMI3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="toy" instantiationToken="{t}">
  <CoSimulation modelIdentifier="toy"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
  </ModelVariables>
  <ModelStructure/>
</fmiModelDescription>
"""

BOMB = "".join(f"{b}: &{b} [{', '.join([f'*{a}'] * 9)}]\n"
               for a, b in zip("abcdefgh", "bcdefghi", strict=True))
BOMB = 'a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]\n' + BOMB


@dataclass
class Case:
    id: str
    files: Files
    argv: tuple[str, ...]
    code: int
    fragments: tuple[str, ...]
    unchanged: tuple[str, ...] = ()  # files that must still hold their bytes afterwards
    absent: tuple[str, ...] = field(default=())  # fragments that must not appear


CASES = [
    # ----------------------------------------------------------------- rulebooks
    Case("rulebook-empty", {"r.rules": ""}, ("check", "r.rules"), 2,
         ("r.rules:1:1: error[E500]: the rulebook has no header",)),
    Case("rulebook-binary", {"r.rules": 'rulebook "ä"\n  '.encode() + b"\xff\xfe\x00"},
         ("check", "r.rules"), 2,
         ("r.rules:2:3: error[E002]: rulebook file is not UTF-8 text (byte 0xff",)),
    Case("rulebook-latin-1", {"r.rules": RULEBOOK.replace("Slip above", "Glissement \xe9")
                              .encode("latin-1")}, ("check", "r.rules"), 2,
         ("r.rules:5:23: error[E002]: rulebook file is not UTF-8 text (byte 0xe9",)),
    Case("rulebook-folder", {"r.rules": FOLDER}, ("check", "r.rules"), 2,
         ("r.rules: error[E002]: rulebook file expected, but r.rules is a folder",)),
    Case("rulebook-missing", {}, ("check", "r.rules"), 2,
         ("r.rules: error[E002]: rulebook file not found: r.rules",)),
    Case("rulebook-unreadable", {"notes": "a file, not a folder"}, ("check", "notes/r.rules"), 2,
         ("notes/r.rules: error[E002]: cannot read rulebook file notes/r.rules: Not a directory",)),
    Case("rulebook-nested-too-deeply",
         {"r.rules": RULEBOOK + "const deep = " + "abs(" * 3000 + "1" + ")" * 3000 + "\n"},
         ("check", "r.rules"), 2, ("r.rules:23:1: error[E001]: expression nested too deeply",),
         absent=("abs(" * 60,)),  # a long source line is shown as a window around the caret
    Case("rulebook-long-sum", {"r.rules": RULEBOOK + "const sum = " + "1 + " * 3000 + "1\n"},
         ("check", "r.rules"), 2, ("r.rules:23:1: error[E001]: expression nested too deeply",)),
    Case("rulebook-crlf", {"r.rules": RULEBOOK.replace("\n", "\r\n")}, ("check", "r.rules"), 0,
         ("r.rules: ok",)),
    Case("rulebook-crlf-error-line", {"r.rules": RULEBOOK.replace("\n", "\r\n")
                                      .replace("limit  = critical_slip", "limit  = critcal")},
         ("check", "r.rules"), 2, ("r.rules:14:12: error[E101]: unknown name 'critcal'",)),
    Case("rulebook-constant-divided-by-zero", {"r.rules": RULEBOOK.replace(
        "const critical_slip = 70 %", "const critical_slip = 70 % / 0")}, ("check", "r.rules"),
         2, ("r.rules:4:23: error[E402]: constant 'critical_slip' is not a finite number",)),
    Case("rulebook-limit-divided-by-zero", {"r.rules": RULEBOOK.replace(
        "limit  = critical_slip", "limit  = 1 m / 0 m")}, ("check", "r.rules"), 2,
         ("r.rules:14:12: error[E402]: the limit of index 'I_s' is not a finite number",)),
    Case("rulebook-path-with-spaces-and-unicode", {"räder prüfung.rules": RULEBOOK},
         ("check", "räder prüfung.rules"), 0, ("räder prüfung.rules: ok",)),
    Case("explain-missing", {}, ("explain", "r.rules"), 2, ("rulebook file not found: r.rules",)),
    Case("fmt-syntax-error-leaves-the-file",
         {"r.rules": RULEBOOK.replace("rank by", "rank by by")}, ("fmt", "r.rules"), 2,
         ("r.rules:22:12: error[E001]: unexpected name 'risk'",), unchanged=("r.rules",)),
    Case("fmt-not-utf8-leaves-the-file", {"r.rules": b"rulebook \xff"}, ("fmt", "r.rules"), 2,
         ("r.rules:1:10: error[E002]",), unchanged=("r.rules",)),
    Case("fmt-check-writes-nothing", {"r.rules": RULEBOOK.replace("limit  =", "limit =")},
         ("fmt", "--check", "r.rules"), 1, ("would reformat r.rules",), unchanged=("r.rules",)),
    # ----------------------------------------------------------------- campaign file
    Case("campaign-empty", {"campaign.yaml": ""}, RUN, 2,
         ("campaign.yaml:1:1: error[C101]: a campaign file is a mapping",)),
    Case("campaign-a-list", {"campaign.yaml": "- a\n- b\n"}, RUN, 2,
         ("campaign.yaml:1:1: error[C101]",)),
    Case("campaign-folder", {"campaign.yaml": FOLDER}, RUN, 2,
         ("campaign.yaml: error[C010]: campaign file expected, but campaign.yaml is a folder",)),
    Case("campaign-missing", {}, RUN, 2,
         ("campaign.yaml: error[C010]: campaign file not found: campaign.yaml",)),
    Case("campaign-not-utf8", {"campaign.yaml": CAMPAIGN.replace("name: cli", "name: cl\xef")
                               .encode("latin-1")}, RUN, 2,
         ("campaign.yaml:1:9: error[C010]: campaign file is not UTF-8 text (byte 0xef",)),
    Case("campaign-tab", campaign(("  path: toy.fmu", "\tpath: toy.fmu")), RUN, 2,
         ("campaign.yaml:3:1: error[C000]: invalid YAML: found character '\\t'",)),
    Case("campaign-duplicate-key", campaign(append="runs: 7\n"), RUN, 2,
         ("campaign.yaml:22:1: error[C002]: duplicate key 'runs'",)),
    # a merge key's mapping gives what the mapping does not: a key it writes twice is still
    # a duplicate, a mistake in a merged value is said where the anchored mapping writes it
    Case("campaign-merge-key-duplicate",
         campaign(('    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}',
                   '    initial.x: &n {distribution: normal, mean: "0 m", std: "1 cm"}\n'
                   '    initial.y: {<<: *n, std: "2 cm", std: "3 cm"}')), RUN, 2,
         ("campaign.yaml:13:38: error[C002]: duplicate key 'std'",)),
    Case("campaign-merged-value-wrong",
         campaign(('    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}',
                   '    initial.x: &n {distribution: normal, mean: "0 m", std: "1 parsec"}\n'
                   '    initial.y: {<<: *n, std: "2 cm"}')), RUN, 2,
         ("campaign.yaml:12:60: error[C100]: uncertainty.parameters.initial.x.std: unknown "
          "unit 'parsec'",),
         absent=("initial.y",)),
    # a key is a name: one YAML reads as a boolean or a number (said as a list index, or the
    # same key as another: true and 1, 0x10 and 16) is refused at it, quoted in the hint
    *(Case(f"campaign-key-{key}", campaign(("  arc:", f"  {key}:")), RUN, 2,
           (f"campaign.yaml:17:3: error[C001]: the key {key} is read by YAML as {kind}, not as "
            f"a name", f'hint: quote it to keep it as a name: "{key}"'),
           absent=("duplicate key", "paths[", "Input should"))
      for key, kind in (("true", "a boolean"), ("0x10", "a whole number"),
                        ("-1", "a whole number"), ("2024-01-01", "a date"),
                        ("null", "null (no value)"), (".inf", "a number"))),
    Case("campaign-key-16-beside-0x10", campaign(("  straight:", "  0x10:"), ("  arc:", "  16:")),
         RUN, 2, ("campaign.yaml:15:3: error[C001]: the key 0x10 is read by YAML as a whole "
                  "number, not as a name",), absent=("duplicate key",)),
    # a value of the wrong type: what is expected there, with an example, not pydantic's
    # "Input should be a valid list" or "Unable to extract tag using discriminator"
    *(Case(f"campaign-type-{name}", campaign(*edits, append=append), RUN, 2, fragments,
           absent=("Input should", "Unable to extract", "Datetimes provided"))
      for name, edits, append, fragments in (
          ("distribution-missing",
           (('initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}', "initial.x: {}"),),
           "", ("campaign.yaml:12:16: error[C100]: uncertainty.parameters.initial.x."
                "distribution: missing required key: which distribution, one of 'fixed', "
                "'normal', 'truncated_normal', 'uniform' or 'log_normal'",
                'hint: for example {distribution: normal, mean: "0 m", std: "1 cm"}')),
          ("path-without-commands", (("  arc:\n" + STRAIGHT.replace("0 deg", "20 deg"),
                                      "  arc:\n"),), "",
           ("campaign.yaml:17:7: error[C100]: paths.arc: expected a list, got nothing",
            "hint: for example [{max_wheel_rate: \"0.05 rad/s\", delta_position: \"1 m\", "
            "delta_heading: \"0 deg\"}], or one command per '- ' line")),
          ("expect-empty", (), "expect:\n",
           ("campaign.yaml:22:8: error[C100]: expect: expected a list, got nothing",
            "hint: for example expect: [{path: straight, verdict: pass}], or expect: [] for "
            "none")),
          ("waivers-empty", (), "waivers:\n",
           ("campaign.yaml:22:9: error[C100]: waivers: expected a list, got nothing",)),
          ("seed-not-whole", (("seed: 5", "seed: 1.5"),), "",
           ("campaign.yaml:10:9: error[C100]: uncertainty.seed: expected a whole number, got "
            "1.5", "hint: for example seed: 3")),
          ("origin-one-value", (), 'environment:\n  terrain: {origin: "-2 m"}\n',
           ("campaign.yaml:23:21: error[C100]: environment.terrain.origin: expected a list of 2 "
            "values, got '-2 m'", 'hint: for example origin: ["-2 m", "-2 m"] (x, y)')),
          ("until-with-a-time", (),
           "waivers:\n  - {rule: acceptable_risk, reason: x, approved_by: me, "
           "until: 2030-01-01 10:00:00}\n",
           ("campaign.yaml:23:64: error[C100]: waivers[0].until: expected a date without a "
            "time of day, got 2030-01-01 10:00:00 (a waiver holds up to and including the day "
            "it names)", "hint: for example until: 2027-03-31")))),
    Case("campaign-unknown-key", campaign(append="runz: 7\n"), RUN, 2,
         ("campaign.yaml:22:1: error[C100]: runz: unknown key",)),
    Case("campaign-billion-laughs", {**campaign(), "campaign.yaml": BOMB + CAMPAIGN}, RUN, 2,
         ("error[C003]: the document expands to more than 100000 values",)),
    Case("campaign-python-tag", campaign(append='x: !!python/object/apply:os.system ["true"]\n'),
         RUN, 2, ("campaign.yaml:22:4: error[C004]: YAML tag "
                  "'tag:yaml.org,2002:python/object/apply:os.system' is not allowed",)),
    Case("campaign-nested-too-deeply", campaign(append="x: " + "[" * 5000 + "]" * 5000 + "\n"),
         RUN, 2, ("error[C000]: invalid YAML: nested too deeply",)),
    Case("campaign-runs-zero", campaign(("runs: 6", "runs: 0")), RUN, 2,
         ("campaign.yaml:6:7: error[C100]: runs: expected a whole number of runs from 1 to "
          "1000000 or 'auto', got 0",)),
    Case("campaign-runs-negative", campaign(("runs: 6", "runs: -3")), RUN, 2,
         ("campaign.yaml:6:7: error[C100]: runs:",)),
    Case("campaign-runs-true", campaign(("runs: 6", "runs: true")), RUN, 2,
         ("campaign.yaml:6:7: error[C100]: runs: expected a whole number of runs from 1 to "
          "1000000 or 'auto', got true",)),
    Case("campaign-runs-text", campaign(("runs: 6", "runs: many")), RUN, 2,
         ("campaign.yaml:6:7: error[C100]: runs:",)),
    Case("campaign-workers-zero", campaign(("workers: 1", "workers: 0")), RUN, 2,
         ("campaign.yaml:7:10: error[C201]",)),
    Case("campaign-workers-too-many", campaign(("workers: 1", "workers: 1025")), RUN, 2,
         ("campaign.yaml:7:10: error[C201]: workers: expected 'auto' or a number from 1 to "
          "1024, got 1025",)),
    # one message for a word that is neither a number nor auto (pydantic gave one per type)
    Case("campaign-workers-text", campaign(("workers: 1", "workers: many")), RUN, 2,
         ("campaign.yaml:7:10: error[C100]: workers: expected 'auto' or a whole number of "
          "worker processes from 1 to 1024, got \"many\"",),
         absent=("Input should be", "expected 'auto', got")),
    Case("campaign-workers-yes", campaign(("workers: 1", "workers: true")), RUN, 2,
         ("campaign.yaml:7:10: error[C100]: workers: expected 'auto' or a whole number of "
          "worker processes from 1 to 1024, got true",), absent=("Input should be",)),
    Case("option-workers-too-many", campaign(), (*RUN, "--workers", "1025"), 2,
         ("argument --workers: at most 1024 worker processes, got 1025",)),
    Case("campaign-seed-text", campaign(("seed: 5", "seed: abc")), RUN, 2,
         ("campaign.yaml:10:9: error[C100]: uncertainty.seed",)),
    Case("campaign-seed-negative", campaign(("seed: 5", "seed: -5")), RUN, 2,
         ("campaign.yaml:10:9: error[C100]: uncertainty.seed",)),
    Case("campaign-seed-above-2-64", campaign(("seed: 5", f"seed: {2**64}")), RUN, 2,
         ("campaign.yaml:10:9: error[C100]: uncertainty.seed: a seed is a whole number from 0 "
          f"to 2^64 - 1 ({2**64 - 1}), got {2**64}",)),
    Case("option-seed-above-2-64", campaign(), (*RUN, "--seed", str(2**64)), 2,
         (f"argument --seed: a seed is a whole number from 0 to 2^64 - 1 ({2**64 - 1}), got "
          f"{2**64}",)),
    Case("option-seed-full-width", campaign(), (*RUN, "--seed", "\uff17"), 2,
         ("argument --seed: expected a whole number written with the digits 0-9, got '\uff17'",)),
    Case("campaign-full-width-digit", campaign(('std: "1 cm"', 'std: "\uff11 cm"')), RUN, 2,
         ("campaign.yaml:12:58: error[C100]: uncertainty.parameters.initial.x.std: '\uff11' "
          "(FULLWIDTH DIGIT ONE) is not one of the ASCII digits 0-9: write '1 cm'",)),
    Case("campaign-arabic-indic-digit", campaign(("low: 0.05", 'low: "0.\u0660\u0665"')), RUN, 2,
         ("campaign.yaml:13:47: error[C100]: uncertainty.parameters.toy.slip.low: '\u0660' "
          "(ARABIC-INDIC DIGIT ZERO) is not one of the ASCII digits 0-9: write '0.05'",)),
    Case("campaign-number-underflows", campaign(('std: "1 cm"', 'std: "1e-400 cm"')), RUN, 2,
         ("campaign.yaml:12:58: error[C100]: uncertainty.parameters.initial.x.std: 1e-400 is "
          "too small for a double: it would be read as 0",)),
    Case("campaign-yaml-float-underflows", campaign(("low: 0.05", "low: 1.0e-400")), RUN, 2,
         ("campaign.yaml:13:44: error[C100]: uncertainty.parameters.toy.slip.low: 1.0e-400 is "
          "too small for a double: it would be read as 0",)),
    Case("campaign-zero-commands", campaign((f"  straight:\n{STRAIGHT}", "  straight: []\n")),
         RUN, 2, ("campaign.yaml:15:13: error[C100]: paths.straight: expected at least 1 value, "
                  "got 0",)),
    Case("campaign-100-commands", campaign((f"  straight:\n{STRAIGHT}",
                                            "  straight:\n" + STRAIGHT * 100)), RUN, 2,
         ("campaign.yaml:15:3: error[C403]: paths.straight: 100 commands, but toy.fmu takes at "
          "most 8",)),
    Case("campaign-path-name-with-a-slash", campaign(("  arc:", "  arc/left:")), RUN, 2,
         ("campaign.yaml:17:3: error[C100]: paths.arc/left: path name 'arc/left' is not usable",)),
    Case("campaign-path-name-too-long", campaign(("  arc:", f"  {'p' * 101}:")), RUN, 2,
         ("campaign.yaml:17:3: error[C100]:", "is not usable: give a non-empty name of at "
          "most 100 characters",)),
    Case("campaign-path-name-with-a-nul", campaign(("  arc:", '  "a\\0b":')), RUN, 2,
         ("campaign.yaml:17:3: error[C100]:", "path name 'a\\x00b' is not usable",)),
    Case("campaign-path-name-with-a-tab", campaign(("  arc:", '  "a\\tb":')), RUN, 2,
         ("campaign.yaml:17:3: error[C100]:", "path name 'a\\tb' is not usable",)),
    *(Case(f"campaign-path-named-{name}", campaign(("  arc:", f'  "{dots}":')), RUN, 2,
           (f"campaign.yaml:17:3: error[C100]: paths.{dots}: path name '{dots}' is not usable: "
            "'.' and '..' mean this folder and the one above in a file path",),
           absent=("give a non-empty name",))
      for name, dots in (("dot", "."), ("dot-dot", ".."))),
    # texts the results file stores, and file names: no NUL, no lone surrogate (h5py refused
    # them with a traceback after the last run's outputs were set aside)
    Case("campaign-name-with-a-nul", campaign(("name: cli", 'name: "cl\\0i"')), RUN, 2,
         ("campaign.yaml:1:7: error[C100]: name: character 3 is a NUL (\\0), which no text "
          "stored in the results file or file name can hold",)),
    Case("campaign-name-with-a-lone-surrogate", campaign(("name: cli", 'name: "cl\\ud800"')),
         RUN, 2, ("campaign.yaml:1:7: error[C100]: name: character 3 is a lone surrogate "
                  "(\\ud800)",)),
    Case("campaign-output-with-a-nul", campaign(("output: out", 'output: "o\\0ut"')), RUN, 2,
         ("error[C100]: output: character 2 is a NUL (\\0)",)),
    # a waiver's `path: all` means every path: a path of that name would widen its waivers
    Case("campaign-path-named-all", campaign(("  arc:", "  all:")), RUN, 2,
         ("campaign.yaml:17:3: error[C100]: paths.all: path name 'all' is reserved: a "
          "waiver's `path: all` means every path",)),
    Case("campaign-path-named-three-dots", campaign(("  arc:", '  "...":')), RUN, 1,
         ("CI verdicts",)),
    Case("campaign-empty-path-name", campaign(("  arc:", '  "":')), RUN, 2,
         ("campaign.yaml:17:3: error[C100]: paths.: path name '' is not usable",)),
    Case("campaign-a-billion-runs", campaign(("runs: 6", "runs: 1000000000")), RUN, 2,
         ("campaign.yaml:6:7: error[C100]: runs: expected a whole number of runs from 1 to "
          "1000000 or 'auto', got 1000000000",)),
    Case("option-a-billion-runs", campaign(), ("campaign.yaml", "--runs", "1000000000"), 2,
         ("argument --runs: at most 1000000 runs per path, got 1000000000",)),
    Case("campaign-wrong-unit", campaign(('"20 deg"', '"20 m"')), RUN, 2,
         ("campaign.yaml:18:77: error[C100]: paths.arc[0].delta_heading: expected an angle, got "
          '"20 m" (a length)',)),
    Case("campaign-bare-number", campaign(('"20 deg"', "20")), RUN, 2,
         ("campaign.yaml:18:77: error[C100]: paths.arc[0].delta_heading: expected an angle",)),
    Case("campaign-nan", campaign(('"20 deg"', '"nan deg"')), RUN, 2,
         ("campaign.yaml:18:77: error[C100]",)),
    Case("campaign-negative-wheel-rate", campaign(('"0.1 rad/s"', '"-0.1 rad/s"')), RUN, 2,
         ("campaign.yaml:16:24: error[C100]: paths.straight[0].max_wheel_rate",)),
    Case("campaign-negative-std", campaign(('std: "1 cm"', 'std: "-1 cm"')), RUN, 2,
         ("campaign.yaml:12:57: error[C100]: uncertainty.parameters.initial.x.std",)),
    Case("campaign-unknown-distribution", campaign(("uniform", "gaussian")), RUN, 2,
         ("campaign.yaml:13:30: error[C100]: uncertainty.parameters.toy.slip: unknown "
          "distribution 'gaussian'",)),
    Case("campaign-terrain-size-overflows",
         campaign(("paths:", 'environment:\n  terrain:\n    synthetic: {size: "4 m", '
                   'cell: "1e-200 m"}\npaths:')), RUN, 2,
         ("error[C100]: environment.terrain.synthetic: size 4 m with cell 1e-200 m gives "
          "4e+200 × 4e+200 grid nodes, more than 16000000",)),
    # wider than 2000 km: the rover model's rut grid over it overflowed its count of cells
    # (out of memory, or a crash: exit 3)
    *(Case(f"campaign-synthetic-terrain-{name}",
           campaign(("paths:", 'environment:\n  terrain:\n    synthetic: {size: '
                     f'"{size}", cell: "100 km"}}\npaths:')), RUN, 2,
           (f"campaign.yaml:16:23: error[C100]: environment.terrain.synthetic.size: expected at "
            f"most 2000 km, got {shown} m: the rover model starts within 1000 km of the "
            "terrain's origin, so a terrain is at most 2000 km wide",))
      for name, size, shown in (("40000-km-wide", "40000 km", "40000000"),
                                ("just-over-2000-km-wide", "2000.001 km", "2000001"))),
    # a slope over the whole size lifting the ground beyond 100 km: said at the section, not
    # at the terrain file written from it (45 deg over 200 km is 100 km: just inside)
    Case("campaign-synthetic-terrain-beyond-100-km",
         campaign(("paths:", 'environment:\n  terrain:\n    synthetic: {size: "200.002 km", '
                   'cell: "100.001 km", slope: "45 deg"}\npaths:')), RUN, 2,
         ("campaign.yaml:16:16: error[C100]: environment.terrain.synthetic: the terrain it "
          "describes is not plausible: height 100001 m at row 0, column 0 (0-based) is beyond "
          "±100000 m of the datum", "hint: the slope over the whole size, or the roughness"),
         absent=("terrain.dem",)),
    Case("campaign-synthetic-terrain-rough-beyond-100-km",
         campaign(("paths:", 'environment:\n  terrain:\n    synthetic: {size: "4 m", '
                   'cell: "1 cm", roughness: "1e300 m"}\npaths:')), RUN, 2,
         ("error[C100]: environment.terrain.synthetic: the terrain it describes is not "
          "plausible",), absent=("terrain.dem", "RuntimeWarning")),
    Case("campaign-rock-of-two-semi-axes",
         campaign(("paths:", 'environment:\n  rocks:\n    - {x: "0.5 m", y: "0 m", '
                   'semi_axes: ["1 cm", "1 cm"]}\npaths:')), RUN, 2,
         ("campaign.yaml:16:41: error[C100]: environment.rocks[0].semi_axes: expected 3 "
          "values, got 2",), absent=("missing required key",)),
    *(Case(f"campaign-rock-{name}",
           campaign(("paths:", 'environment:\n  rocks:\n    - {x: "0.5 m", y: "0 m", '
                     f'radius: "5 cm", embed: "{embed}"}}\npaths:')), RUN, 2,
           # at the embed, in the unit it is written in
           ("campaign.yaml:16:53: error[C100]: environment.rocks[0].embed: expected a depth "
            f"from 0 {unit} (on the ground) to under the rock's height {height} {unit} (fully "
            f"buried), got {embed}{floats}",))
      for name, embed, unit, height, floats in (
          ("floating", "-1 m", "m", "0.1", ": a negative depth would float it"),
          ("buried", "10 cm", "cm", "10", ""), ("far-below", "1 m", "m", "0.1", ""),
          ("floating-by-a-millimetre", "-1 mm", "mm", "100",
           ": a negative depth would float it"))),
    # expectations the rulebook could never judge: found after simulating everything (✗ n/a,
    # exit 1); now refused before, at the entry
    Case("campaign-expects-a-collision-chance-the-rulebook-never-computes",
         campaign(append='expect:\n  - {path: arc, max_collision_chance: {L2: "10 %"}}\n'),
         RUN, 2, ("campaign.yaml:23:40: error[C220]: expect[0].max_collision_chance.L2: rulebook "
                  "cli-test 0.1.0 has no chance of obstacle level L2 (one whose name ends in L2); "
                  "it reads no collisions: the chance is never computed, so this expectation "
                  "could never be judged",), absent=("Path evaluation",)),
    Case("campaign-expects-only-levels-the-rulebook-has-chances-for",
         with_files(campaign(append='expect:\n  - {path: arc, max_collision_chance: '
                                    '{L2: "100 %", any: "100 %", L3: "10 %"}}\n'),
                    test__rules=RULEBOOK.replace("verdict acceptable_risk", "chance slip_L2 = "
                                                 "max over time (max over wheels "
                                                 "(abs(wheel.slip))) > 50 %\n\nverdict "
                                                 "acceptable_risk")),
         RUN, 2, ("campaign.yaml:23:67: error[C220]: expect[0].max_collision_chance.L3: rulebook "
                  "cli-test 0.1.0 has no chance of obstacle level L3",),
         absent=("max_collision_chance.L2", "max_collision_chance.any")),
    Case("campaign-expects-the-risk-of-a-path-the-command-rules-reject",
         with_files(campaign(append='expect:\n  - {path: arc, max_mean_risk: "60 %"}\n'),
                    test__rules=RULEBOOK.replace("verdict acceptable_risk", TURN_RULE
                                                 + "\nverdict acceptable_risk")),
         RUN, 2, ("campaign.yaml:23:17: error[C220]: expect[0].max_mean_risk: path 'arc' breaks "
                  "the command rule 'max_turn' of rulebook cli-test 0.1.0: it is rejected and "
                  "never simulated, so its mean risk could never be judged",),
         absent=("Path evaluation",)),
    Case("campaign-expects-the-risk-of-a-path-whose-command-rule-is-waived",
         with_files(campaign(append='expect:\n  - {path: arc, max_mean_risk: "100 %"}\n'
                                    "waivers:\n  - {rule: max_turn, path: arc, reason: r, "
                                    "approved_by: a, until: 2099-01-01, command_rules: true}\n"),
                    test__rules=RULEBOOK.replace("verdict acceptable_risk", TURN_RULE
                                                 + "\nverdict acceptable_risk")),
         RUN, 0, ("CI expectations: 1 of 1 held (exit 0)",), absent=("C220",)),
    Case("campaign-waiver-until-a-number",
         campaign(append="waivers:\n  - {rule: acceptable_risk, reason: r, approved_by: a, "
                         "until: 20990101}\n"), RUN, 2,
         ("error[C100]: waivers[0].until: expected a date written YYYY-MM-DD (e.g. 2027-03-31), "
          "got the number 20990101",)),
    Case("campaign-waiver-until-a-quoted-number",
         campaign(append="waivers:\n  - {rule: acceptable_risk, reason: r, approved_by: a, "
                         "until: \"4102444800\"}\n"), RUN, 2,
         ("error[C100]: waivers[0].until: expected a date written YYYY-MM-DD (e.g. 2027-03-31), "
          "got the number '4102444800'",)),
    # an FMU given where the campaign goes: it was "campaign file rover.fmu is 645 KiB; at most
    # 256 KiB is accepted", or not UTF-8 text for a smaller one
    *(Case(f"campaign-is-an-fmu-{size}", {"rover.fmu": fmu}, ("rover.fmu", "--runs", "2"), 2,
           ("rover.fmu: error[C101]: rover.fmu is an FMU (a zip archive holding a "
            "modelDescription.xml), not a campaign file (YAML): a campaign names its FMU under "
            "fmu.path", "hint: give the campaign file that names it, e.g. `fmu: {path: "
            "rover.fmu}`"), absent=("KiB", "UTF-8"), unchanged=("rover.fmu",))
      for size, fmu in (("small", TOY), ("large", lambda toy: _zip_of({
          "modelDescription.xml": b"<fmiModelDescription/>",
          "binaries/x": os.urandom(300 * 1024)})))),
    Case("campaign-is-a-zip", {"c.zip": lambda toy: _zip_of({"campaign.yaml": b"name: c"})},
         ("c.zip", "--runs", "2"), 2,
         ("c.zip: error[C101]: c.zip is a zip archive, not a campaign file (YAML)",),
         absent=("fmu.path",)),
    Case("campaign-is-a-rulebook", {"test.rules": RULEBOOK},
         ("test.rules", "--runs", "2", "--quiet", "--no-report"), 2,
         ("test.rules:1:1: error[C101]: test.rules is a rulebook (it starts with 'rulebook "
          "\"…\"'), not a campaign", "hint: check it with `idefix-verify check test.rules`"),
         unchanged=("test.rules",)),
    # a rulebook within the limits whose formatted text would not be: one long constant name
    # aligns every other constant's value to its column
    Case("fmt-would-grow-past-the-limit",
         {"big.rules": RULEBOOK.replace(
             "const critical_slip", f"const c_{'x' * 60} = 1\n"
             + "".join(f"const c{i} = 1\n" for i in range(3000)) + "const critical_slip")},
         ("fmt", "big.rules"), 2,
         ("big.rules: error[E900]: formatted, big.rules would be over a rulebook's limits",
          "the file is left as it is"), unchanged=("big.rules",)),
    # said at the value that makes the runs this long, not at `simulation:`
    Case("campaign-huge-stop-time", campaign(('extra_time: "2 s"', 'extra_time: "1e9 s"')), RUN,
         2, ("campaign.yaml:21:15: error[C404]: paths.straight: a run would last 1e+09 s at an "
             "output interval of 0.5 s: 2e+09 samples per run, more than 1000000",)),
    Case("campaign-huge-stop-time-in-flow-style",
         campaign(('simulation:\n  output_interval: "0.5 s"\n  extra_time: "2 s"\n',
                   'simulation: {extra_time: "1e12 s"}\n')), RUN,
         2, ("campaign.yaml:19:26: error[C404]: paths.straight: a run would last 1e+12 s at an "
             "output interval of 0.1 s: 1e+13 samples per run, more than 1000000",)),
    # a wheel rate so slow the chain itself takes years: said at the path, not the settings
    Case("campaign-crawling-chain", campaign(('{max_wheel_rate: "0.1 rad/s", delta_position: '
                                              '"0.1 m", delta_heading: "0 deg"}',
                                              '{max_wheel_rate: "1e-7 rad/s", delta_position: '
                                              '"0.1 m", delta_heading: "0 deg"}')), RUN,
         2, ("campaign.yaml:15:3: error[C404]: paths.straight: a run would last",)),
    # a command longer than a double holds (its duration inf): said at the path, not a crash
    Case("campaign-endless-chain", campaign(('{max_wheel_rate: "0.1 rad/s", delta_position: '
                                             '"0.1 m", delta_heading: "0 deg"}',
                                             '{max_wheel_rate: "0.1 rad/s", delta_position: '
                                             '"1e308 m", delta_heading: "0 deg"}')), RUN,
         2, ("campaign.yaml:15:3: error[C404]: paths.straight: a run would last longer than a "
             "number can say",)),
    # a margin that makes a short chain's run endless: said at the margin, not at the path
    *(Case(f"campaign-margin-{name}",
           campaign(('  extra_time: "2 s"', f'  extra_time: "2 s"\n  duration_margin: {margin}')),
           RUN, 2, (f"campaign.yaml:22:20: error[{code}]: {said}",),
           # the margin stretches both paths: said once, at it
           absent=("paths.arc: a run would last",))
      for name, margin, code, said in (
          ("inf", ".inf", "C100", "simulation.duration_margin: expected a finite value, got inf"),
          ("nan", ".nan", "C100", "simulation.duration_margin: expected a finite value, got nan"),
          ("1e308", "1e308", "C404", "paths.straight: a run would last longer than a number can "
                                     "say (duration_margin × the chain's duration is beyond a "
                                     "double)"),
          ("1e12", "1e12", "C404", "paths.straight: a run would last 1e+13 s"))),
    # an output interval so fine the runs hold too many samples: said once, at the interval
    Case("campaign-fine-output-interval", campaign(('output_interval: "0.5 s"',
                                                    'output_interval: "1e-5 s"')), RUN,
         2, ("campaign.yaml:20:20: error[C404]: paths.straight: a run would last",)),
    Case("campaign-rulebook-missing", campaign(("rulebook: test.rules", "rulebook: nope.rules")),
         RUN, 2, ("campaign.yaml:4:11: error[C200]: rulebook: rulebook 'nope.rules' not found",)),
    Case("campaign-rulebook-with-errors",
         with_files(campaign(), test__rules=RULEBOOK.replace("= critical_slip", "= critcal")),
         RUN, 2, ("test.rules:14:12: error[E101]: unknown name 'critcal'",)),
    # ----------------------------------------------------------------- FMU
    Case("fmu-missing", campaign(("path: toy.fmu", "path: nope.fmu")), RUN, 2,
         ("campaign.yaml:3:9: error[C200]: fmu.path: FMU 'nope.fmu' not found",)),
    Case("fmu-a-folder", campaign(("path: toy.fmu", "path: .")), RUN, 2,
         ("campaign.yaml:3:9: error[C200]: fmu.path: FMU '.' is a folder, not a file",)),
    Case("fmu-not-a-zip", with_files(campaign(), toy__fmu="not a zip"), RUN, 2,
         ("campaign.yaml:3:9: error[C400]:", "not a readable FMU (File is not a zip file)")),
    # FMI 3.0 co-simulation is run; this one lacks every variable the campaign names.
    Case("fmu-fmi3-lacking-the-variables",
         with_files(campaign(), toy__fmu=fmu_with_description(FMI3)), RUN, 2,
         ("campaign.yaml:12:5: error[C401]: uncertainty.parameters.initial.x: unknown FMU "
          "parameter 'initial.x' in toy.fmu", "campaign.yaml:3:3: error[C401]: the signal map "
          "shipped in toy.fmu names 30 variable(s) it does not have: 't', 'x', 'y'",
          "campaign.yaml:3:3: error[C507]: toy.fmu takes no command chain as parameters")),
    # (model exchange only is run with fmpy's solver: tests/fmu/test_fmu_foreign_runner.py)
    Case("fmu-without-an-interface",
         with_files(campaign(), toy__fmu=fmu_with_description(
             FMI3.replace('  <CoSimulation modelIdentifier="toy"/>\n', ""))), RUN, 2,
         ("campaign.yaml:3:9: error[C400]:", "an FMI 3.0 FMU for nothing; the campaign runner "
          "needs FMI 2.0 or 3.0 co-simulation or model exchange")),
    Case("fmu-unknown-parameter", campaign(("toy.slip:", "toy.slipp:")), RUN, 2,
         ("campaign.yaml:13:5: error[C401]: uncertainty.parameters.toy.slipp: unknown FMU "
          "parameter 'toy.slipp' in toy.fmu", "did you mean 'toy.slip'?")),
    # a variable's name without its group: the grouped name is what was meant
    Case("fmu-parameter-without-its-group", campaign(("toy.slip:", "slip:")), RUN, 2,
         ("campaign.yaml:13:5: error[C401]: uncertainty.parameters.slip: unknown FMU "
          "parameter 'slip' in toy.fmu", "did you mean 'toy.slip'? (a variable is named with "
          "its group)")),
    Case("fmu-parameter-mapped-to-nothing",
         campaign(("  path: toy.fmu", "  path: toy.fmu\n  parameters:\n    soil.nothing: c")),
         RUN, 2, ("campaign.yaml:5:5: error[C401]: fmu.parameters.soil.nothing: unknown FMU "
                  "variable 'soil.nothing' in toy.fmu",)),
    Case("fmu-signal-mapped-to-nothing",
         campaign(("  path: toy.fmu", "  path: toy.fmu\n  signals:\n    body.x: x")),
         RUN, 2, ("campaign.yaml:5:5: error[C401]: fmu.signals.body.x: unknown FMU variable",)),
    Case("fmu-signal-map-without-a-signal-the-rulebook-reads",
         campaign(("  path: toy.fmu", "  path: toy.fmu\n  signals:\n    x: x\n    y: y\n"
                                      "    energy: energy\n    command: command")), RUN, 2,
         ("campaign.yaml:4:3: error[C405]: fmu.signals: the rulebook reads 'wheel.slip', which "
          "the signal map does not provide",)),
    Case("fmu-parameter-of-wrong-dimension", campaign(("low: 0.05, high: 0.25",
                                                       'low: "1 m", high: "2 m"')), RUN, 2,
         ("campaign.yaml:13:15: error[C402]: uncertainty.parameters.toy.slip: expected a ratio",)),
    # the chain delivery sets these from each path's commands: a value here never counts
    Case("regolith-sets-a-chain-parameter",
         campaign(("paths:", 'environment:\n  regolith:\n    chain.max_wheel_rate[0]: '
                             '"0.5 rad/s"\npaths:')), RUN, 2,
         ("campaign.yaml:16:5: error[C515]: environment.regolith.chain.max_wheel_rate[0]: "
          "'chain.max_wheel_rate[0]' is set by each run's command chain",)),
    # the tool computes durations and bodies from the geometry before any run: a wheel of
    # radius 0 divided by zero (a traceback), a negative one said C404 at line 1
    *(Case(f"regolith-{name}-{label}",
           campaign(("paths:", f'environment:\n  regolith: {{rover.{name}: "{value}"}}\npaths:')),
           RUN, 2, (f"campaign.yaml:15:{22 + len(name)}: error[C221]: "
                    f"environment.regolith.rover.{name}: "
                    f"rover.{name} is the rover's geometry: it must be a positive length, got "
                    f"{metres:g} m",), absent=("Traceback", "C404"))
      for name, label, value, metres in (("wheel_radius", "zero", "0 cm", 0.0),
                                         ("wheel_radius", "negative", "-1 cm", -0.01),
                                         ("half_track", "zero", "0 cm", 0.0))),
    # a drawn geometry: at the distribution's nominal value
    Case("uncertain-half-wheelbase-negative",
         campaign(("uncertainty:\n  method: monte_carlo\n  seed: 5\n  parameters:\n",
                   "uncertainty:\n  method: monte_carlo\n  seed: 5\n  parameters:\n"
                   '    rover.half_wheelbase: {distribution: normal, mean: "-2 cm", '
                   'std: "1 mm"}\n')),
         RUN, 2, ("campaign.yaml:12:56: error[C221]: uncertainty.parameters.rover."
                  "half_wheelbase.mean: rover.half_wheelbase is the rover's geometry: it must "
                  "be a positive length, got -0.02 m",)),
    Case("regolith-a-wheel-radius-just-above-zero",
         campaign(("paths:", 'environment:\n  regolith: {rover.wheel_radius: "1 mm"}\npaths:')),
         RUN, 1, ("CI verdicts",), absent=("C221",)),
    Case("regolith-sets-a-parameter-twice",
         campaign(("paths:", 'environment:\n  regolith: {cohesion: "-5 Pa", soil.cohesion: '
                             '"260 Pa"}\npaths:')),
         RUN, 2, ("campaign.yaml:15:33: error[C100]: environment.regolith.soil.cohesion: sets "
                  "soil.cohesion again (as 'cohesion' above); one of the two values would be "
                  "dropped",)),
    Case("regolith-sets-the-chain-count",
         campaign(("paths:", "environment:\n  regolith: {chain.count: 0}\npaths:")), RUN, 2,
         ("error[C515]: environment.regolith.chain.count: 'chain.count' is set by each run's "
          "command chain",)),
    Case("uncertainty-draws-a-chain-parameter",
         campaign(("    toy.slip:", '    chain.delta_position[0]: {distribution: uniform, '
                                     'low: "1 m", high: "2 m"}\n    toy.slip:')), RUN, 2,
         ("error[C515]: uncertainty.parameters.chain.delta_position[0]: "
          "'chain.delta_position[0]' is set by each run's command chain",)),
    # an FMU's own name for a chain parameter (fmu.parameters maps it), set directly
    Case("regolith-sets-a-renamed-chain-parameter",
         campaign(("  path: toy.fmu", "  path: toy.fmu\n  parameters: {toy.slip: chain.count}"),
                  ("paths:", "environment:\n  regolith: {toy.slip: 0.1}\npaths:")), RUN, 2,
         ("error[C515]: environment.regolith.toy.slip: 'toy.slip' is set by each run's command "
          "chain",)),
    Case("regolith-value-of-wrong-dimension",
         campaign(("paths:", 'environment:\n  regolith: {toy.slip: "5 cm"}\npaths:')), RUN, 2,
         ("campaign.yaml:15:24: error[C402]: environment.regolith.toy.slip: expected a ratio "
          "(FMU unit 1), got a length",)),
    # ----------------------------------------------------------------- terrain
    Case("dem-truncated", with_files(campaign(("paths:", "environment:\n  terrain:\n"
                                                "    dem: site.dem\npaths:")),
                                     site__dem=terrain_file(cut=8)), RUN, 2,
         ("site.dem:7:1: error[F204]: height grid holds 64 bytes, expected 72",)),
    Case("dem-nan", with_files(campaign(("paths:", "environment:\n  terrain:\n"
                                          "    dem: site.dem\npaths:")),
                               site__dem=terrain_file(heights=np.array([0.0] * 4 + [np.nan]
                                                                       + [0.0] * 4))), RUN, 2,
         ("site.dem:7:1: error[F204]: height grid holds NaN or infinite values",)),
    Case("dem-wrong-header", with_files(campaign(("paths:", "environment:\n  terrain:\n"
                                                   "    dem: site.dem\npaths:")),
                                        site__dem=b"IDEFIX 2\n" + bytes(72)), RUN, 2,
         ("site.dem:1:1: error[F204]: expected 'IDEFIX-TERRAIN 1' as the first line",)),
    Case("dem-nx-not-a-number", with_files(campaign(("paths:", "environment:\n  terrain:\n"
                                                      "    dem: site.dem\npaths:")),
                                           site__dem=terrain_file(
                                               header=TERRAIN_HEADER.replace("nx 3", "nx three"))),
         RUN, 2, ("site.dem:2:4: error[F204]: header needs 'nx N', 'ny N', 'origin X Y', 'cell C': "
                  "'three' is not a whole number",)),
    Case("dem-cell-nan", with_files(campaign(("paths:", "environment:\n  terrain:\n"
                                               "    dem: site.dem\npaths:")),
                                    site__dem=terrain_file(
                                        header=TERRAIN_HEADER.replace("cell 1.0", "cell nan"))),
         RUN, 2, ("site.dem:5:6: error[F204]: 'cell': not a number: 'nan'",)),
    Case("dem-rock-level-unknown", with_files(campaign(("paths:", "environment:\n  terrain:\n"
                                                        "    dem: site.dem\npaths:")),
                                              site__dem=terrain_file(header=TERRAIN_HEADER.replace(
                                                  "rocks 0\n", "rocks 1\nrock 0 0 0 1 1 1 L9\n"))),
         RUN, 2, ("site.dem:7:18: error[F204]: rock level 'L9': expected L1, L2 or L3",)),
    Case("dem-csv-bad-value", with_files(campaign(("paths:", "environment:\n  terrain:\n"
                                                    "    dem: site.csv\n    cell: \"1 m\"\n"
                                                    "paths:")),
                                         site__csv="0,0,0\n0,x,0\n0,0,0\n"), RUN, 2,
         ("site.csv:2:3: error[F207]: not a number: 'x'",)),
    Case("dem-npy-of-python-objects",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.npy\n"
                              "    cell: \"1 m\"\npaths:")), site__npy=NPY_OBJECTS), RUN, 2,
         ("site.npy: error[F203]: cannot read DEM: not an array of numbers: numpy reads it as "
          "pickled Python objects, which are never loaded",), absent=("allow_pickle",)),
    # arrays of something else than numbers: a cast fails, takes a date for its day count or
    # drops an imaginary part
    *(Case(f"dem-npy-of-{name}",
           with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.npy\n"
                                "    cell: \"1 m\"\npaths:")), site__npy=_npy(array)), RUN, 2,
           (f"site.npy: error[F203]: cannot read DEM: the array holds {words}, not numbers",))
      for name, array, words in (
          ("text", np.array([["a", "b"], ["c", "d"]]), "text (<U1)"),
          ("bytes", np.array([[b"a", b"b"], [b"c", b"d"]]), "bytes (|S1)"),
          ("records", np.zeros((2, 2), dtype=[("h", "<f8")]), "records (|V8)"),
          ("dates", np.array([["2024-01-01"] * 2] * 2, dtype="datetime64[D]"),
           "dates (<M8[D])"),
          ("complex", np.ones((2, 2), dtype=complex), "complex numbers (<c16)"))),
    Case("dem-npy-that-is-a-text-file",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.npy\n"
                              "    cell: \"1 m\"\npaths:")), site__npy=b"hello\n"), RUN, 2,
         ("site.npy: error[F203]: cannot read DEM: not a .npy file: it has no NumPy header",),
         absent=("pickle",)),
    Case("dem-csv-not-utf8",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.csv\n"
                              "    cell: \"1 m\"\npaths:")),
                    site__csv="0,0,0\n0,\xe9,0\n0,0,0\n".encode("latin-1")), RUN, 2,
         ("site.csv:2:3: error[F203]: DEM file is not UTF-8 text (byte 0xe9",
          "hint: save the file as UTF-8"), absent=("codec",)),
    Case("dem-npy-is-an-npz-archive",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.npy\n"
                              "    cell: \"1 m\"\npaths:")), site__npy=_npz()), RUN, 2,
         ("site.npy: error[F203]: cannot read DEM: the file is an .npz archive of arrays",)),
    Case("dem-is-the-terrain-file-the-run-writes",
         {**campaign(("paths:", "environment:\n  terrain:\n    dem: out/terrain.dem\n"
                      "paths:")), "out": FOLDER, "out/terrain.dem": terrain_file()}, RUN, 2,
         ("campaign.yaml:16:10: error[C217]: environment.terrain.dem: the DEM is the terrain "
          "file this campaign writes into its output folder (terrain.dem)",),
         unchanged=("out/terrain.dem",)),
    # heights beyond ±100 km: numpy's overflow warnings and a run that passed, or exit 3
    *(Case(f"dem-npy-{name}",
           with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.npy\n"
                                "    cell: \"1 m\"\npaths:")), site__npy=_npy(array)), RUN, 2,
           (f"site.npy: error[F206]: DEM height {shown} m at row {row}, column {column} "
            "(0-based) is beyond ±100000 m of the datum",))
      for name, array, shown, row, column in (
          ("one-height-1e308", np.array([[0.0, 0.0, 0.0], [0.0, 1e308, 0.0], [0.0] * 3]),
           "1e+308", 1, 1),
          ("of-heights-1e308", np.full((3, 3), 1e308), "1e+308", 0, 0),
          ("height-just-below-minus-100-km",
           np.array([[0.0, -100000.001, 0.0], [0.0] * 3, [0.0] * 3]), "-100000", 0, 1))),
    Case("dem-csv-height-beyond-100-km",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.csv\n"
                              "    cell: \"1 m\"\npaths:")),
                    site__csv="0,0,0\n0,100000.001,0\n0,0,0\n"), RUN, 2,
         ("site.csv:2:3: error[F207]: height '100000.001' is beyond ±100000 m of the datum",)),
    Case("dem-height-beyond-100-km",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.dem\npaths:")),
                    site__dem=terrain_file(heights=np.array([0.0] * 5 + [-1e200] + [0.0] * 3))),
         RUN, 2, ("site.dem:7:1: error[F204]: height grid: height -1e+200 m at row 1, column 2 "
                  "(0-based) is beyond ±100000 m of the datum",)),
    Case("dem-rock-too-large",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.dem\npaths:")),
                    site__dem=terrain_file(header=TERRAIN_HEADER.replace(
                        "rocks 0\n", "rocks 1\nrock 0 0 0 1 1e200 1\n"))),
         RUN, 2, ("site.dem:7:14: error[F204]: rock semi-axis 1e+200 m: at most 1000 m",)),
    # the terrain file's header as the rover model reads it: a second item replaced the first
    # there (a 100 m map from 'cell 0.02' then 'cell 0.5'), values after the ones it wants were
    # ignored ('cell 0.02 0.04' taken as square)
    *(Case(f"dem-{name}",
           with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.dem\npaths:")),
                      site__dem=terrain_file(header=TERRAIN_HEADER.replace(old, new))),
           RUN, 2, (f"site.dem:{where}: error[F204]: {said}",))
      for name, old, new, where, said in (
          ("cell-twice", "cell 1.0\n", "cell 1.0\ncell 0.5\n", "6:1",
           "'cell' given again: line 5 gives it already"),
          ("nx-twice", "ny 3\n", "ny 3\nnx 4\n", "4:1",
           "'nx' given again: line 2 gives it already"),
          ("cell-of-two-values", "cell 1.0", "cell 1.0 2.0", "5:10",
           "'cell' takes one value: '2.0' is one too many"),
          ("nx-of-two-values", "nx 3", "nx 3 7", "2:6",
           "'nx' takes one value: '7' is one too many"),
          ("file-origin-of-three-values", "origin -1.0 -1.0", "origin -1.0 -1.0 5", "4:18",
           "'origin' takes two values: '5' is one too many"),
          ("heights-with-a-value", "heights", "heights 9", "7:9",
           "'heights' takes no value: '9' is one too many"),
          # the rover model's C reader takes 1_000 for 1, Python's float for 1000
          ("cell-with-an-underscore", "cell 1.0", "cell 1_0", "5:6",
           "'cell': not a number: '1_0'"),
          ("rock-after-a-blank-line", "rocks 0\n", "rocks 1\n\nrock 0 0 0 0.1 0.1 0.1\n", "7:1",
           "'rocks 1' (line 6) says 1 rock lines follow it directly; line 7 is no rock line"),
          ("rock-before-its-count", "rocks 0\n", "rock 0 0 0 0.1 0.1 0.1\nrocks 1\n", "6:1",
           "a 'rock' line outside the rock lines: they follow their 'rocks N' line directly, "
           "N of them"),
          ("rock-floating-1-km-up", "rocks 0\n", "rocks 1\nrock 0.5 0 1000 0.05 0.05 0.04\n",
           "7:1", "rock at (0.5 m, 0 m) floats: its lowest point (z - c = 999.96 m) is 999.96 m "
           "above the highest ground under it (0 m)"),
          ("rock-a-grain", "rocks 0\n", "rocks 1\nrock 0.5 0 0 0.05 0.0005 0.04\n", "7:19",
           "rock semi-axis 0.0005 m: at least 0.001 m (a smaller grain is part of the regolith, "
           "which the soil model represents)"),
          # 2 cells of 1e20 m: the rover model's rut grid over it crashed the FMU (exit 3)
          ("cell-1e20-m", "cell 1.0", "cell 1e20", "5:6",
           "cell 1e+20 m with nx 3 makes the grid 2e+20 m wide; at most 2000 km"),
          ("cell-just-over-1000-km", "cell 1.0", "cell 1000000.5", "5:6",
           "cell 1000000.5 m with nx 3 makes the grid 2000001 m wide; at most 2000 km"))),
    # the binary grid after a header without its 'heights' line: never quoted (its NUL bytes
    # were printed as the source line)
    Case("dem-missing-heights-before-the-grid",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.dem\npaths:")),
                    site__dem=terrain_file(header=TERRAIN_HEADER.replace("heights\n", ""))),
         RUN, 2, ("site.dem:7:1: error[F204]: missing 'heights' line: line 7 holds binary data "
                  "(byte 0x00), not header text",
                  "hint: the header ends with a line 'heights'; the binary height grid follows "
                  "it"), absent=("\x00",)),
    # more rocks than the rover model holds: said at their count, before the output folder
    # is taken (the last run's summary stays where it is)
    Case("dem-with-5000-rocks",
         {**with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.dem\n"
                                           "paths:")),
                       site__dem=terrain_file(header=TERRAIN_HEADER.replace(
                           "rocks 0\n", "rocks 5000\n" + "rock 0 0 0 0.1 0.1 0.1\n" * 5000))),
          "out": FOLDER}, RUN, 2,
         ("site.dem:6:7: error[F202]: 5000 rocks; at most 4096 (the rover model holds 4096)",)),
    Case("campaign-with-5001-rocks-by-alias",
         {**campaign(("paths:", 'environment:\n  rocks: [&r {x: "0.5 m", y: "0 m", radius: '
                                '"1 cm"}' + ", *r" * 5000 + "]\npaths:")),
          "out": FOLDER}, RUN, 2,
         ("campaign.yaml:15:10: error[C100]: environment.rocks: 5001 rocks; at most 4096 (the "
          "rover model holds 4096)",)),
    Case("dem-rocks-and-the-campaign-s-over-4096",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.dem\n"
                                        '  rocks: [{x: "0.5 m", y: "0 m", radius: "1 cm"}]\n'
                                        "paths:")),
                    site__dem=terrain_file(header=TERRAIN_HEADER.replace(
                        "rocks 0\n", "rocks 4096\n" + "rock 0 0 0 0.1 0.1 0.1\n" * 4096))),
         RUN, 2, ("campaign.yaml:17:10: error[F202]: environment.rocks: 1 rocks and the 4096 of "
                  "the terrain file make 4097; at most 4096 (the rover model holds 4096)",)),
    # a DEM of bare heights wider than 2000 km by its cell: the FMU ran out of memory or crashed
    Case("dem-npy-cell-making-it-wider-than-2000-km",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.npy\n"
                              '    cell: "1000.001 km"\npaths:')),
                    site__npy=_npy(np.zeros((3, 3)))),
         RUN, 2, ("campaign.yaml:17:11: error[C100]: environment.terrain.cell: a cell of "
                  "1000001 m makes the DEM's 3 x 3 heights 2000002 m wide; at most 2000 km",)),
    Case("dem-npy-cell-1e20-m",
         with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.npy\n"
                              '    cell: "1e20 m"\npaths:')),
                    site__npy=_npy(np.zeros((3, 3)))),
         RUN, 2, ("campaign.yaml:17:11: error[C100]: environment.terrain.cell: expected at most "
                  "2000 km, got 1e+20 m: the rover model starts within 1000 km of the terrain's "
                  "origin, so a terrain is at most 2000 km wide",)),
    # plain ASCII decimal numbers only, as the campaign's: Python's float read 1_000 as 1000,
    # other scripts' digits as theirs, and 1e-400 as 0
    *(Case(f"dem-csv-{name}",
           with_files(campaign(("paths:", "environment:\n  terrain:\n    dem: site.csv\n"
                                "    cell: \"1 m\"\npaths:")),
                      site__csv=f"0,0,0\n0,{value},0\n0,0,0\n"), RUN, 2,
           (f"site.csv:2:3: error[F207]: {said}",))
      for name, value, said in (
          ("underscore", "1_000", "not a number: '1_000'"),
          ("arabic-indic-digit", "\u0663", "'\u0663' (ARABIC-INDIC DIGIT THREE) is not one of "
           "the ASCII digits 0-9: write '3'"),
          ("fullwidth-digits", "\uff11\uff12", "'\uff11' (FULLWIDTH DIGIT ONE) is not one of the "
           "ASCII digits 0-9: write '12'"),
          ("underflow", "1e-400", "1e-400 is too small for a double: it would be read as 0 (write "
           "0 if zero is meant)"))),
    Case("dem-csv-nan", with_files(campaign(("paths:", "environment:\n  terrain:\n"
                                                    "    dem: site.csv\n    cell: \"1 m\"\n"
                                                    "paths:")),
                                         site__csv="0,0,0\n0,nan,0\n0,0,0\n"), RUN, 2,
         ("site.csv:2:3: error[F207]: not a finite height: 'nan'",)),
    Case("rock-outside-the-terrain",
         campaign(("paths:", 'environment:\n  rocks:\n    - {x: "100 m", y: "0 m", '
                             'radius: "4 cm"}\npaths:')), RUN, 2,
         ("campaign.yaml:16:7: error[C206]: environment.rocks[0]: (100 m, 0 m) is outside the "
          "terrain",)),
    # a rock 1e200 m wide overflowed the collision geometry: every test was silently false
    *(Case(f"rock-{name}",
           campaign(("paths:", 'environment:\n  rocks:\n    - {x: "0.5 m", y: "0 m", '
                               f'{size}}}\npaths:')), RUN, 2,
           (f"campaign.yaml:16:{column}: error[C100]: environment.rocks[0].{where}: expected a "
            f"rock radius or semi-axis of at most 1000 m, got {shown} m (a larger rock is a "
            "hill or a crater: give it in the terrain's dem)",))
      for name, size, column, where, shown in (
          ("radius-1e200", 'radius: "1e200 m", embed: "1e200 m"', 38, "radius", "1e+200"),
          ("radius-just-above-1-km", 'radius: "1000.001 m"', 38, "radius", "1000.001"),
          ("semi-axis-1e300", 'semi_axes: ["1 cm", "1e300 m", "1 cm"]', 50, "semi_axes[1]",
           "1e+300"))),
    # a rock of 1e-300 m: how deep a point lay inside it overflowed (a traceback after the
    # reference runs)
    Case("rock-semi-axis-1e-300-m",
         campaign(("paths:", 'environment:\n  rocks:\n    - {x: "0.5 m", y: "0 m", '
                             'semi_axes: ["1e-300 m", "5 cm", "5 cm"]}\npaths:')), RUN, 2,
         ("campaign.yaml:16:42: error[C100]: environment.rocks[0].semi_axes[0]: expected a rock "
          "radius or semi-axis of at least 0.001 m, got 1e-300 m (a smaller grain is part of the "
          "regolith, which the soil model represents; the collision check resolves 0.1 mm)",)),
    Case("rock-negative-radius",
         campaign(("paths:", 'environment:\n  rocks:\n    - {x: "1 m", y: "0 m", '
                             'radius: "-4 cm"}\npaths:')), RUN, 2,
         ("campaign.yaml:16:36: error[C100]: environment.rocks[0].radius: must be above 0",)),
    Case("simulation-margin-below-one",
         campaign(('  extra_time: "2 s"', '  extra_time: "2 s"\n  duration_margin: -1')), RUN, 2,
         ("campaign.yaml:22:20: error[C100]: simulation.duration_margin: must be at least 1.0",)),
    Case("dem-origin-of-three-values",
         campaign(("paths:", 'environment:\n  terrain:\n    dem: flat.npy\n    cell: "2 cm"\n'
                             '    origin: ["1 m", "2 m", "3 m"]\npaths:')), RUN, 2,
         ("campaign.yaml:18:13: error[C100]: environment.terrain.origin: expected at most 2 "
          "values, got 3",)),
    *(Case(f"synthetic-terrain-slope-{name}",
           campaign(("paths:", "environment:\n  terrain:\n    synthetic:\n"
                               f'      slope: "{value}"\npaths:')), RUN, 2,
           ("campaign.yaml:17:14: error[C100]: environment.terrain.synthetic.slope: expected an "
            f"inclination from 0 deg to under 90 deg (slope_direction gives the way it falls), "
            f"got {shown} deg",))
      for name, value, shown in (("a-wall", "90 deg", "90"), ("past-a-wall", "100 deg", "100"),
                                 ("negative", "-2 deg", "-2"),
                                 ("in-radians", "1.6 rad", "91.6732"))),
    *(Case(f"synthetic-terrain-with-a-dem-{key}",
           campaign(("paths:", f"environment:\n  terrain:\n    {key}: {value}\n    synthetic:\n"
                               '      size: "2 m"\npaths:')), RUN, 2,
           (f"campaign.yaml:16:{column}: error[C204]: environment.terrain.{key}: only a .npy or "
            f".csv DEM takes a {key}",))
      for key, value, column in (("cell", '"5 cm"', 11), ("origin", '["0 m", "0 m"]', 13))),
    # a number that fits a double, its unit taking it past one in SI: no traceback
    Case("uncertainty-beyond-a-double-in-si",
         campaign(('std: "1 cm"}', 'std: "1e306 km"}')), RUN, 2,
         ("campaign.yaml:12:58: error[C100]: uncertainty.parameters.initial.x.std: '1e306 km' "
          "is too large: in SI (m) it is beyond a double",)),
    Case("synthetic-terrain-negative-roughness",
         campaign(("paths:", "environment:\n  terrain:\n    synthetic:\n"
                             '      roughness: "-3 mm"\npaths:')), RUN, 2,
         ("campaign.yaml:17:18: error[C100]: environment.terrain.synthetic.roughness: expected "
          "a length of 0 m or more, got -0.003 m",)),
    # environment mistakes at the line that says them
    Case("keep-out-bow-tie", campaign(("paths:", "environment:\n  keep_out:\n    - name: k\n"
                                                 '      polygon: [["0 m", "0 m"], ["1 m", "1 m"], '
                                                 '["1 m", "0 m"], ["0 m", "1 m"]]\npaths:')),
         RUN, 2, ("campaign.yaml:17:16: error[E622]: environment.keep_out[0].polygon: area k: "
                  "polygon is not simple (its edges cross)",)),
    # a spike out and back along one line, a vertex on another edge: no simple polygon, so
    # the area cut into triangles would not be the one drawn
    Case("keep-out-spike",
         campaign(("paths:", "environment:\n  keep_out:\n    - name: k\n"
                             '      polygon: [["0 m", "0 m"], ["2 m", "0 m"], ["2 m", "1 m"], '
                             '["1 m", "1 m"], ["1 m", "2 m"], ["1 m", "1.5 m"], ["0 m", "1 m"]]'
                             "\npaths:")),
         RUN, 2, ("campaign.yaml:17:16: error[E622]: environment.keep_out[0].polygon: area k: "
                  "polygon is not simple (edge 5 turns back along edge 4, a spike)",)),
    Case("keep-out-vertex-on-an-edge",
         campaign(("paths:", "environment:\n  keep_out:\n    - name: k\n"
                             '      polygon: [["0 m", "0 m"], ["2 m", "0 m"], ["2 m", "2 m"], '
                             '["1 m", "0 m"], ["0 m", "2 m"]]\npaths:')),
         RUN, 2, ("campaign.yaml:17:16: error[E622]: environment.keep_out[0].polygon: area k: "
                  "polygon is not simple (vertex 4 lies on edge 1)",)),
    Case("keep-out-on-a-line", campaign(("paths:", "environment:\n  keep_out:\n    - name: k\n"
                                                   '      polygon: [["0 m", "0 m"], ["1 m", "1 m"],'
                                                   ' ["2 m", "2 m"]]\npaths:')),
         RUN, 2, ("campaign.yaml:17:16: error[E622]: environment.keep_out[0].polygon: area k: "
                  "polygon has no area",)),
    Case("keep-out-closed-ring",
         campaign(("paths:", "environment:\n  keep_out:\n    - name: k\n"
                             '      polygon: [["0 m", "0 m"], ["1 m", "0 m"], ["1 m", "1 m"], '
                             '["0 m", "0 m"]]\npaths:')),
         RUN, 2, ("campaign.yaml:17:16: error[E622]: environment.keep_out[0].polygon: area k: "
                  "the last vertex repeats the first",)),
    Case("keep-out-names-twice",
         campaign(("paths:", "environment:\n  keep_out:\n"
                             '    - {name: k, polygon: [["0 m", "0 m"], ["1 m", "0 m"], '
                             '["1 m", "1 m"]]}\n'
                             '    - {name: k, polygon: [["2 m", "0 m"], ["3 m", "0 m"], '
                             '["3 m", "1 m"]]}\npaths:')),
         RUN, 2, ("campaign.yaml:17:14: error[E613]: environment.keep_out[1]: the name 'k' is "
                  "taken by keep_out[0]",)),
    Case("keep-out-named-like-a-rock",
         campaign(("paths:", "environment:\n  rocks:\n"
                             '    - {x: "0.5 m", y: "1 m", radius: "4 cm", level: L2}\n'
                             "  keep_out:\n"
                             '    - {name: rock1, polygon: [["2 m", "0 m"], ["3 m", "0 m"], '
                             '["3 m", "1 m"]]}\npaths:')),
         RUN, 2, ("campaign.yaml:18:14: error[E613]: environment.keep_out[0]: the name 'rock1' "
                  "is taken by the campaign's rock 1 (environment.rocks[0]: rocks are named "
                  "rock1, rock2, … in their order)",)),
    Case("rock-levels-reversed",
         campaign(("paths:", 'environment:\n  rock_levels: {l1_max_size: "10 cm", '
                             'l2_max_size: "3 cm"}\npaths:')),
         RUN, 2, ("campaign.yaml:15:16: error[E611]: environment.rock_levels: need 0 < "
                  "l1_max_size <= l2_max_size, got 0.1 m and 0.03 m",)),
    # expectations that no path could break: a risk or chance above 100 %
    *(Case(f"expect-{name}", campaign(append=f"expect:\n  - {{path: straight, {text}}}\n"),
           RUN, 2, (f"campaign.yaml:{line}: error[C100]: expect[0].{where}: expected a risk or "
                    f"chance from 0 to 100 %, got {shown} (a bare number is a fraction",))
      for name, text, where, line, shown in (
          ("mean-risk-bare-30", "max_mean_risk: 30", "max_mean_risk", "23:37", "3000 %"),
          ("mean-risk-150-percent", 'max_mean_risk: "150 %"', "max_mean_risk", "23:37",
           "150 %"),
          ("collision-chance-150-percent", 'max_collision_chance: {L1: "150 %"}',
           "max_collision_chance.L1", "23:49", "150 %"))),
    Case("synthetic-terrain-too-large",
         campaign(("paths:", 'environment:\n  terrain:\n    synthetic: {size: "4 km", '
                             'cell: "1 mm"}\npaths:')), RUN, 2,
         ("campaign.yaml:16:16: error[C100]: environment.terrain.synthetic: size 4000 m with "
          "cell 0.001 m gives",)),
    Case("synthetic-cell-zero",
         campaign(("paths:", 'environment:\n  terrain:\n    synthetic: {cell: "0 cm"}\n'
                             'paths:')), RUN, 2,
         ("campaign.yaml:16:23: error[C100]: environment.terrain.synthetic.cell",)),
    # ----------------------------------------------------------------- YAML values
    # a scalar the safe constructor cannot read as what its form or tag says
    *(Case(f"yaml-{name}", campaign(("name: cli", f"name: {value}")), RUN, 2,
           (f"campaign.yaml:1:7: error[C000]: invalid YAML: {shown} is not a valid {kind}",
            "hint: quote it to keep it as text"))
      for name, value, shown, kind in (
          ("no-such-day", "2024-02-30", "'2024-02-30'", "timestamp"),
          ("no-such-hour", "2024-01-01 25:00:00", "'2024-01-01 25:00:00'", "timestamp"),
          ("int-tag", '!!int "abc"', "'abc'", "int"),
          ("int-tag-hex", "!!int 0x", "'0x'", "int"),
          ("float-tag", '!!float "abc"', "'abc'", "float"),
          ("bool-tag", '!!bool "maybe"', "'maybe'", "bool"),
          ("timestamp-tag", '!!timestamp "nope"', "'nope'", "timestamp"))),
    Case("yaml-bad-date-as-a-key", campaign(append="2024-02-30: x\n"), RUN, 2,
         ("error[C000]: invalid YAML: '2024-02-30' is not a valid timestamp",)),
    # ----------------------------------------------------------------- output folder
    Case("output-is-a-file", campaign(("output: out", "output: test.rules")), RUN, 2,
         ("campaign.yaml:5:9: error[C205]: output folder", "test.rules cannot be used: it is a "
          "file"), unchanged=("test.rules",)),
    # an empty one (a template's unfilled field) would write beside the campaign file
    Case("output-empty", campaign(("output: out", 'output: ""')), RUN, 2,
         ("campaign.yaml:5:9: error[C100]: output: an empty folder name: give the folder the "
          "results go to (results/NAME), or '.' for the campaign file's own folder",)),
    Case("output-blank", campaign(("output: out", 'output: "  "')), RUN, 2,
         ("campaign.yaml:5:9: error[C100]: output: an empty folder name",)),
    Case("output-below-a-file", campaign(("output: out", "output: test.rules/out")), RUN, 2,
         ("campaign.yaml:5:9: error[C205]: output folder", "cannot be used: Not a directory")),
    Case("out-option-is-a-file", campaign(), (*RUN, "--out", "test.rules"), 2,
         ("argument --out: test.rules is a file, not a folder",), unchanged=("test.rules",)),
    Case("junit-is-a-folder", with_files(campaign(), reports=FOLDER),
         (*RUN, "--junit", "reports"), 2,
         ("argument --junit: reports is a folder; give a file name",)),
    Case("junit-is-the-output-folder", campaign(), (*RUN, "--junit", "out"), 2,
         ("error[C207]: cannot write the JUnit file out: Is a directory",
          "hint: the results are in")),
    Case("junit-is-the-campaign", campaign(), (*RUN, "--junit", "campaign.yaml"), 2,
         ("error[C703]: --junit campaign.yaml is a file this command reads or writes",),
         unchanged=("campaign.yaml",), absent=("campaign.previous.yaml",)),
    Case("junit-is-the-rulebook", campaign(), (*RUN, "--junit", "test.rules"), 2,
         ("error[C703]: --junit test.rules is a file this command reads or writes",),
         unchanged=("test.rules",)),
    Case("junit-is-the-summary", campaign(), (*RUN, "--junit", "out/summary.json"), 2,
         ("error[C703]: --junit out/summary.json is a file this command reads or writes",)),
    Case("junit-is-the-fmu", campaign(), (*RUN, "--junit", "toy.fmu"), 2,
         ("error[C703]: --junit toy.fmu is a file this command reads or writes",),
         unchanged=("toy.fmu",)),
    Case("junit-is-some-other-file", with_files(campaign(), notes="my notes\n"),
         (*RUN, "--junit", "notes"), 2,
         ("error[C703]: --junit notes is an existing file that is not a JUnit report",
          "hint: give a new file name"), unchanged=("notes",)),
    Case("junit-is-an-xml-file-but-no-report", with_files(campaign(), **{
        "data.xml": '<?xml version="1.0"?>\n<data/>\n'}), (*RUN, "--junit", "data.xml"), 2,
         ("error[C703]: --junit data.xml is an existing file that is not a JUnit report",),
         unchanged=("data.xml",)),
    Case("evaluate-junit-is-the-results", {"results.h5": "x"},
         ("evaluate", "results.h5", "--junit", "results.h5"), 2,
         ("error[C703]: --junit results.h5 is a file this command reads or writes",),
         unchanged=("results.h5",)),
    Case("evaluate-junit-is-the-summary", {"results.h5": "x", "summary.json": "{}"},
         ("evaluate", "results.h5", "--junit", "summary.json"), 2,
         ("error[C703]: --junit summary.json is a file this command reads or writes",),
         unchanged=("summary.json",)),
    Case("evaluate-junit-is-the-rulebook", {"results.h5": "x", "r.rules": RULEBOOK},
         ("evaluate", "results.h5", "--rulebook", "r.rules", "--junit", "r.rules"), 2,
         ("error[C703]: --junit r.rules is a file this command reads or writes",),
         unchanged=("r.rules",)),
    Case("junit-below-a-file", campaign(), (*RUN, "--junit", "test.rules/junit.xml"), 2,
         ("argument --junit: cannot write test.rules/junit.xml:", "test.rules is a file")),
    Case("evaluate-out-is-a-file", {"results.h5": "x", "notes": "x"},
         ("evaluate", "results.h5", "--out", "notes"), 2,
         ("argument --out: notes is a file, not a folder",)),
    Case("report-out-is-a-file", {"results.h5": "x", "notes": "x"},
         ("report", "results.h5", "-o", "notes"), 2,
         ("argument -o/--out: notes is a file, not a folder",)),
    Case("build-fmu-output-is-a-folder", {"out": FOLDER}, ("build-fmu", "-o", "out"), 2,
         ("argument --output/-o: out is a folder; give a file name",)),
    # ----------------------------------------------------------------- run options
    Case("option-scheduler-not-an-address", campaign(), (*RUN, "--scheduler", "no address"), 2,
         ("argument --scheduler: 'no address' is not a Dask scheduler address: missing port "
          "number",)),
    Case("option-runs-zero", campaign(), ("campaign.yaml", "--runs", "0"), 2,
         ("argument --runs: expected a positive whole number, got 0",)),
    Case("option-runs-negative", campaign(), ("campaign.yaml", "--runs", "-1"), 2,
         ("argument --runs: expected a positive whole number, got -1",)),
    Case("option-workers-zero", campaign(), ("campaign.yaml", "--workers", "0"), 2,
         ("argument --workers: expected a positive whole number, got 0",)),
    Case("option-seed-text", campaign(), ("campaign.yaml", "--seed", "abc"), 2,
         ("argument --seed: expected a whole number, got 'abc'",)),
    Case("option-run-timeout-infinite", campaign(), ("campaign.yaml", "--run-timeout", "inf"), 2,
         ("argument --run-timeout: expected a number of seconds >= 0 (0: no timeout), "
          "got inf",)),
    # ----------------------------------------------------------------- results files
    Case("evaluate-not-hdf5", {"results.h5": "plain text"}, ("evaluate", "results.h5"), 2,
         ("results.h5: error[H002]: cannot open results file results.h5: not an HDF5 file",),
         absent=("--resume",)),
    Case("evaluate-foreign-hdf5", {"results.h5": foreign_hdf5}, ("evaluate", "results.h5"), 2,
         ("results.h5: error[H003]: results.h5 is not an idefix results file",)),
    Case("evaluate-missing", {}, ("evaluate", "results.h5"), 2,
         ("results.h5: error[H001]: results file results.h5 not found",)),
    Case("evaluate-a-folder", {"results.h5": FOLDER}, ("evaluate", "results.h5"), 2,
         ("results.h5: error[H002]",)),
    Case("report-not-hdf5", {"results.h5": "plain text"}, ("report", "results.h5"), 2,
         ("results.h5: error[H002]: cannot open results file results.h5: not an HDF5 file",)),
    # ----------------------------------------------------------------- the command line
    Case("no-arguments", {}, (), 2, ("usage: idefix-verify",)),
    Case("unknown-command", {}, ("chek", "r.rules"), 2,
         ("unknown command 'chek' (did you mean 'check'?)",)),
    Case("empty-command", {}, ("",), 2, ("unknown command ''",)),
    Case("unknown-option", {}, ("--bogus",), 2, ("unrecognized arguments: --bogus",)),
    Case("run-options-before-the-campaign", campaign(), ("--runs", "0", "campaign.yaml"), 2,
         ("idefix-verify run: error: argument --runs: expected a positive whole number",)),
]


def materialise(folder: Path, files: Files, toy: Path) -> None:
    for name, content in files.items():
        target = folder / name
        if content is FOLDER:
            target.mkdir()
        elif content is TOY:
            target.write_bytes(toy.read_bytes())
        elif callable(content):
            target.write_bytes(content(toy))
        elif isinstance(content, bytes):
            target.write_bytes(content)
        else:
            target.write_bytes(str(content).encode("utf-8"))


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_a_user_mistake_gets_a_clear_message_and_its_exit_code(
        case: Case, tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    materialise(tmp_path, case.files, cli_toy_fmu)
    before = {name: (tmp_path / name).read_bytes() for name in case.unchanged}
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings(record=True) as raised:
        warnings.simplefilter("always")
        code = main(list(case.argv))
    captured = capsys.readouterr()
    output = captured.out + captured.err
    assert "Traceback" not in output
    # numpy's and scipy's own words ("overflow encountered in square") never reach the user
    assert [str(w.message) for w in raised if issubclass(w.category, RuntimeWarning)] == []
    assert code == case.code, output
    flat = " ".join(output.split())  # rich may wrap long lines
    for fragment in case.fragments:
        assert fragment in output or " ".join(fragment.split()) in flat, output
    for fragment in case.absent:
        assert fragment not in output
    for name, content in before.items():
        assert (tmp_path / name).read_bytes() == content, f"{name} was changed"


@pytest.mark.parametrize("module_name", COMMAND_MODULES)
def test_every_command_has_a_working_help(module_name: str,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    module = importlib.import_module(f"idefix_rules.cli.{module_name}")
    assert main([module.NAME, "--help"]) == 0
    out = capsys.readouterr().out
    assert f"usage: idefix-verify {module.NAME}" in out


@pytest.mark.parametrize("where", ["campaign", "option"])
def test_a_seed_above_2_64_changes_nothing_in_the_output_folder(
        where: str, tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    # both paths pass acceptable_risk on their point estimate (risk 19 % <= 50 %), not decided
    # at 2 runs: without `expect:` every path must be shown to pass: exit 1
    assert main(list(RUN)) == 1
    before = {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()}
    if where == "campaign":
        text = (tmp_path / "campaign.yaml").read_text().replace("seed: 5", f"seed: {2**64}")
        (tmp_path / "campaign.yaml").write_text(text)
    argv = [*RUN, "--seed", str(2**64)] if where == "option" else list(RUN)
    capsys.readouterr()
    assert main(argv) == 2
    output = "".join(capsys.readouterr())
    assert "Traceback" not in output and "2^64 - 1" in output
    after = {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()}
    if where == "campaign":
        # a campaign refused sets aside the summary and report that would speak for it
        # (docs/operations.md); its results stay, as they were
        moved = {name: name.replace(".", ".previous.", 1) for name in before
                 if name == "summary.json" or name.endswith((".html", ".png"))}
        assert moved and "results.h5" not in moved
        before = {moved.get(name, name): content for name, content in before.items()}
    # no stub results file
    assert after == before


def test_ctrl_c_exits_130_without_a_traceback(monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.cli import check

    def interrupted(args: object) -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(check, "run", interrupted)
    assert main(["check", "any.rules"]) == 130
    captured = capsys.readouterr()
    assert "interrupted" in captured.err and "Traceback" not in captured.err


def test_an_incomplete_results_file_is_a_user_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.campaign.storage.store import FORMAT

    results = tmp_path / "results.h5"
    with h5py.File(results, "w") as file:
        file.attrs["format"] = FORMAT
        file.create_group("paths")
    for command in ("report", "evaluate"):
        code = main([command, str(results)])
        output = "".join(capsys.readouterr())
        assert code == 2, output
        assert "Traceback" not in output
        assert f"{results}: error[H003]: {results} is an incomplete idefix results file " \
               "(no provenance group)" in output


def test_fmt_keeps_a_symlink_and_the_file_mode(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    real = tmp_path / "real.rules"
    real.write_text(RULEBOOK.replace("limit  =", "limit ="))
    real.chmod(0o640)
    link = tmp_path / "link.rules"
    link.symlink_to(real)
    assert main(["fmt", str(link)]) == 0
    assert link.is_symlink()
    assert real.read_text() == formatted_text(RULEBOOK, "real.rules")
    assert real.stat().st_mode & 0o777 == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.rules", "real.rules"]


def test_fmt_that_cannot_write_leaves_the_file_and_exits_2(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.cli import fmt

    path = tmp_path / "r.rules"
    original = RULEBOOK.replace("limit  =", "limit =")
    path.write_text(original)

    def disk_full(source: object, target: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(fmt.os, "replace", disk_full)
    assert main(["fmt", str(path)]) == 2
    output = "".join(capsys.readouterr())
    assert f"{path}: error[E010]: cannot write {path}: No space left on device; the file is " \
           "unchanged" in " ".join(output.split())
    assert "Traceback" not in output
    assert path.read_text() == original
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.rules"]  # no temporary left


def test_resume_without_results_warns_and_resume_of_another_campaign_is_refused(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    # nothing to resume, so a whole run: both paths pass, not decided at 2 runs: exit 1
    assert main([*RUN, "--resume"]) == 1
    output = " ".join("".join(capsys.readouterr()).split())
    assert "warning: nothing to resume in" in output
    assert (tmp_path / "out" / "results.h5").is_file()
    assert main([*RUN, "--resume", "--seed", "6"]) == 2
    output = "".join(capsys.readouterr())
    assert "results.h5: error[H010]: cannot resume" in output
    assert "its seed is 5, this campaign's is 6" in " ".join(output.split())
    assert "Traceback" not in output


def test_evaluate_with_a_rulebook_reading_a_signal_the_results_lack(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    # both paths pass acceptable_risk on their point estimate (risk 19 % <= 50 %), not decided
    # at 2 runs: without `expect:` every path must be shown to pass: exit 1
    assert main(list(RUN)) == 1
    results = tmp_path / "out" / "results.h5"
    assert main(["evaluate", str(results)]) == 1  # the stored rulebook: the same verdicts
    with h5py.File(results, "r+") as file:  # as if the FMU map had not provided the slip
        del file["paths/arc/runs/signals/wheel.slip"]
    capsys.readouterr()
    assert main(["evaluate", str(results)]) == 2
    output = "".join(capsys.readouterr())
    assert f"{results}: error[H011]: the rulebook reads 'wheel.slip', which the stored runs " \
           "of path 'arc' do not hold" in " ".join(output.split())
    assert "Traceback" not in output


def test_an_unreachable_dask_scheduler_is_exit_3_and_says_so(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import dask

    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        code = main([*RUN, "--scheduler", "tcp://127.0.0.1:1"])
    output = "".join(capsys.readouterr())
    assert code == 3
    assert "cannot reach the Dask scheduler tcp://127.0.0.1:1" in output
    assert "Traceback" not in output


def test_evaluating_an_interrupted_campaign_says_how_to_continue_it(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    # both paths pass acceptable_risk on their point estimate (risk 19 % <= 50 %), not decided
    # at 2 runs: without `expect:` every path must be shown to pass: exit 1
    assert main(list(RUN)) == 1
    results = tmp_path / "out" / "results.h5"
    with h5py.File(results, "r+") as file:
        file.attrs["state"] = "interrupted"
    capsys.readouterr()
    # every run is stored (only the state says interrupted): none counts as failed, the
    # same verdicts (passing, not decided): exit 1
    assert main(["evaluate", str(results)]) == 1
    output = " ".join("".join(capsys.readouterr()).split())
    assert f"warning: {results} holds a campaign that is interrupted: runs never simulated " \
           "count as failed" in output
    assert f"--resume --out {results.parent} --runs 2 --seed 5" in output


def test_report_of_results_whose_evaluation_was_never_stored_evaluates_them(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Not a mistake: the report scores the stored runs with the stored rulebook itself."""
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    # both paths pass acceptable_risk on their point estimate (risk 19 % <= 50 %), not decided
    # at 2 runs: without `expect:` every path must be shown to pass: exit 1
    assert main(list(RUN)) == 1
    results = tmp_path / "out" / "results.h5"
    with h5py.File(results, "r+") as file:  # as if the campaign stopped before evaluating
        for name in ("evaluation", "paths/straight/evaluation", "paths/arc/evaluation"):
            if name in file:
                del file[name]
    assert main(["report", str(results), "-o", str(tmp_path / "report")]) == 0
    assert "Traceback" not in "".join(capsys.readouterr())
    assert (tmp_path / "report" / "report.html").is_file()


def test_ctrl_c_during_a_campaign_exits_130_with_the_resume_command_once(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.campaign import runner

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(runner, "run_campaign", interrupted)
    assert main([*RUN, "--seed", "9"]) == 130
    output = "".join(capsys.readouterr())
    assert output.count("interrupted") == 1 and "Traceback" not in output
    # RUN's --no-report too: the command continues the campaign as it ran
    assert "continue with `idefix-verify campaign.yaml --resume --runs 2 --seed 9 --no-report`" \
        in output


def test_the_resume_command_printed_for_a_folder_with_a_space_pastes_as_one_argument(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """`idefix-verify my camp.yaml --resume` ran `my` with the arguments `camp.yaml`."""
    import shlex

    from idefix_rules.campaign import runner

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    folder = tmp_path / "sp ace"
    folder.mkdir()
    files = campaign()
    files["my camp.yaml"] = files.pop("campaign.yaml")
    materialise(folder, files, cli_toy_fmu)
    monkeypatch.chdir(folder)
    monkeypatch.setattr(runner, "run_campaign", interrupted)
    monkeypatch.setenv("COLUMNS", "200")
    assert main(["my camp.yaml", "--out", "out $HOME", "--runs", "2", "--quiet",
                 "--no-report"]) == 130
    output = "".join(capsys.readouterr())
    command = "idefix-verify 'my camp.yaml' --resume --out 'out $HOME' --runs 2 --no-report"
    assert f"continue with `{command}`" in output, output
    assert shlex.split(command)[1:4] == ["my camp.yaml", "--resume", "--out"]


def test_ctrl_c_while_the_report_is_written_says_the_answer_and_how_to_write_the_report(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The campaign is complete when the report starts: its answer is said, summary.json
    holds it, and the way on is `report`, not a --resume that would evaluate everything
    again."""
    from idefix_rules.campaign import runner

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(runner, "write_report", interrupted)
    assert main(["campaign.yaml", "--runs", "2", "--quiet"]) == 130
    output = " ".join("".join(capsys.readouterr()).split())
    assert "Traceback" not in output and "--resume" not in output
    assert "Decision:" in output  # the answer, first
    results = tmp_path / "out" / "results.h5"
    assert ("interrupted while writing the report: the results and summary.json are complete "
            "(exit code 1 without the interrupt); write the report with "
            f"`idefix-verify report {results}`") in output
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["exit_code"] == 1 and not (tmp_path / "out" / "report.html").exists()


def test_building_the_fmu_without_a_compiler_is_exit_3_and_says_what_is_missing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))  # no cc, gcc, clang or cmake
    monkeypatch.delenv("CC", raising=False)
    assert main(["build-fmu", "-o", str(tmp_path / "rover.fmu")]) == 3
    output = " ".join("".join(capsys.readouterr()).split())
    assert "building the rover FMU needs a C compiler" in output
    assert "Traceback" not in output


# (old, new, what the line is found by, the message in the campaign's unit)
REFUSED_BY_THE_ROVER = {
    "regolith": ('    n: 1.0\n', '    n: 1.0\n    friction_angle: "85 deg"\n', '"85 deg',
                 "soil.friction_angle = 85 deg out of range: allowed [0, 80 deg]"),
    "uncertainty": ("  parameters:\n", "  parameters:\n    soil.friction_angle: "
                    '{distribution: uniform, low: "84 deg", high: "86 deg"}\n',
                    '{distribution: uniform, low: "84',
                    "soil.friction_angle = 85 deg out of range: allowed [0, 80 deg]"),
    # a pressure and a modulus: compound units, their SI spelled kg/(m·s^2)
    "regolith-pascal": ('    n: 1.0\n', '    n: 1.0\n    cohesion: "-5 Pa"\n', '"-5 Pa',
                        "soil.cohesion = -5 Pa out of range: allowed [0, 1e+06 Pa]"),
    "regolith-modulus": ('k_phi: "820000 N/m^3"', 'k_phi: "-820000 N/m^3"', '"-820000',
                         "soil.k_phi = -820000 N/m^3 out of range: allowed [0, 1e+12 N/m^3]"),
    "uncertainty-kilopascal": (
        "  parameters:\n", "  parameters:\n    soil.cohesion: "
        '{distribution: uniform, low: "-2 kPa", high: "-1 kPa"}\n',
        '{distribution: uniform, low: "-2 kPa"',
        "soil.cohesion = -1.5 kPa out of range: allowed [0, 1000 kPa]"),
}


@pytest.mark.parametrize("where", REFUSED_BY_THE_ROVER)
def test_a_value_the_rover_refuses_points_at_the_campaign_line_that_set_it(
        where: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    # The built-in rover checks its parameters' ranges as it initialises (docs/rover-model.md,
    # "Parameters"): soil.friction_angle at most 80°. 85° is refused in the reference run, and
    # the message names the campaign line that set it, not the FMU file.
    rulebook = Path(__file__).parents[2] / "rulebooks" / "idefix-ops.rules"
    text = (Path(__file__).parents[2] / "campaigns" / "flat-control.yaml").read_text()
    text = text.replace("../rulebooks/idefix-ops.rules", str(rulebook))
    old, new, found_by, expected = REFUSED_BY_THE_ROVER[where]
    assert old in text
    text = text.replace(old, new, 1)
    (tmp_path / "campaign.yaml").write_text(text)
    monkeypatch.chdir(tmp_path)
    code = main(["run", "campaign.yaml", "--runs", "2", "--quiet", "--no-report", "--out", "o"])
    captured = capsys.readouterr()
    output = captured.out + captured.err
    before = text[:text.index(found_by)]
    line, column = before.count("\n") + 1, len(before) - before.rfind("\n")
    assert code == 2, output
    # in the unit the campaign wrote it in, not the FMU's SI (the reference run's value: the
    # given one, or the uniform distribution's median)
    assert f"campaign.yaml:{line}:{column}: error[F110]: " \
           f"parameter {expected}\n" in output, output
    assert "Traceback" not in output and ".fmu: error" not in output


def test_results_stored_before_a_stricter_check_are_scored_again_as_they_were(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A check added to the campaign schema later (an expectation above 100 %, a rock's
    embed, a negative roughness, a waiver's date as a number …) refuses a new run, never a
    stored one: the results file's campaign ran, and evaluate and report read it back."""
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(list(RUN)) == 1
    capsys.readouterr()
    stored = tmp_path / "out" / "results.h5"
    older = CAMPAIGN + (
        "environment:\n  rocks:\n    - {x: \"3 m\", y: \"3 m\", radius: \"2 cm\", "
        "embed: \"-1 cm\"}\n  terrain:\n    synthetic: {roughness: \"-1 mm\"}\n"
        "expect:\n  - {path: straight, max_mean_risk: 30}\n"
        "  - {path: straight, max_collision_chance: {}}\n"
        "waivers:\n  - {rule: acceptable_risk, reason: r, approved_by: a, "
        "until: 4102444800}\n")
    (tmp_path / "older.yaml").write_text(older)
    assert main(["older.yaml", "--runs", "2", "--quiet", "--no-report"]) == 2  # a new run
    capsys.readouterr()
    with h5py.File(stored, "r+") as results:
        del results["provenance/campaign"]
        results["provenance/campaign"] = older
    # the expectation (3000 %) holds; the waiver, read as seconds since 1970 as it was then,
    # waives acceptable_risk until 2100: exit 0
    for argv in (["evaluate", str(stored)], ["report", str(stored), "-o", "site"]):
        code = main(argv)
        output = "".join(capsys.readouterr())
        assert "Traceback" not in output and code == 0, output
    assert (tmp_path / "site" / "report.html").is_file()


def test_a_stored_campaign_this_version_cannot_read_is_d010_not_a_traceback(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """evaluate and diff --results re-score a results file from the campaign it stores: one
    that no longer validates is D010, exit 2 (evaluate ended in pydantic's traceback)."""
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(list(RUN)) == 1
    capsys.readouterr()
    stored = tmp_path / "out" / "results.h5"
    with h5py.File(stored, "r+") as results:
        text = results["provenance/campaign"][()].decode()
        del results["provenance/campaign"]
        results["provenance/campaign"] = text.replace("runs: 6", "runs: six")
    for argv in (["evaluate", str(stored)],
                 ["diff", "test.rules", "test.rules", "--results", str(stored)]):
        code = main(argv)
        output = "".join(capsys.readouterr())
        assert code == 2, output
        assert "Traceback" not in output, output
        assert f"{stored}: error[D010]: the stored campaign cannot be read back: runs: " \
               "expected a whole number of runs from 1 to 1000000 or 'auto', got \"six\"" in \
               output, output


def test_report_into_a_folder_keeps_the_report_already_there(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """report -o DIR sets an existing report.html aside as report.previous.html, as a run does:
    a folder of one's own reports never loses one to another campaign's."""
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(list(RUN)) == 1
    site = tmp_path / "site"
    site.mkdir()
    (site / "report.html").write_text("<html>my own report</html>")
    assert main(["report", str(tmp_path / "out" / "results.h5"), "-o", str(site)]) == 0
    assert "Traceback" not in "".join(capsys.readouterr())
    assert (site / "report.previous.html").read_text() == "<html>my own report</html>"
    assert "my own report" not in (site / "report.html").read_text()


@pytest.mark.parametrize(("address", "words"), [
    ("nonsense://x", "unknown address scheme 'nonsense'"),
    ("tcp://", "it names no host"),
    ("tcp://:8786", "it names no host"),
    ("tcp://scheduler:notaport", "invalid literal for int()"),
    # no port: Dask's client refused it after the output folder had been taken over, and a
    # second such typo replaced the last good results set aside
    ("localhost", "missing port number"),
    ("tcp://127.0.0.1", "missing port number"),
    ("tcp://127.0.0.1:65536", "port 65536 is not from 1 to 65535"),
])
def test_a_scheduler_address_that_is_none_is_a_usage_error_before_anything_runs(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str], address: str, words: str) -> None:
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main([*RUN, "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert f"argument --scheduler: {address!r} is not a Dask scheduler address" in err
    assert words in err and not (tmp_path / "out").exists()


def test_ctrl_c_while_the_report_is_written_still_says_why_the_exit_code_would_be_2(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.campaign import runner

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    waiver = ("waivers:\n  - {rule: acceptable_risk, path: straight, reason: \"x\", "
              "approved_by: \"me\", until: 2099-01-01}\n")
    materialise(tmp_path, campaign(append=waiver), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    # at 40 runs acceptable_risk passes decidedly on straight: the waiver matches nothing
    assert main(["campaign.yaml", "--runs", "40", "--quiet", "--no-report"]) == 2
    plain = "".join(capsys.readouterr())
    assert "error[C215]" in plain
    monkeypatch.setattr(runner, "write_report", interrupted)
    assert main(["campaign.yaml", "--runs", "40", "--quiet"]) == 130
    output = " ".join("".join(capsys.readouterr()).split())
    assert "error[C215]" in output and "(exit code 2 without the interrupt)" in output


def test_diff_judges_each_side_with_the_campaigns_waivers_as_evaluate_does(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A path waived under the stored rulebook is `waived` on both sides of a diff with the
    same rulebook (it was `fail`), and `diff` agrees with `evaluate --rulebook` on it."""
    waiver = ("waivers:\n  - {rule: acceptable_risk, path: straight, reason: \"x\", "
              "approved_by: \"me\", until: 2099-01-01}\n")
    materialise(tmp_path, campaign(append=waiver), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(list(RUN)) == 1
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    stored = {p["name"]: p["verdict"] for p in summary["paths"]}
    assert stored["straight"] == "waived"
    capsys.readouterr()
    assert main(["diff", "test.rules", "test.rules", "--results", "out/results.h5",
                 "--format", "json"]) == 0
    data = json.loads(capsys.readouterr().out)
    found = data["results"] if "files" not in data else data
    sides = {path["name"]: (path["old"]["verdict"], path["new"]["verdict"])
             for result in found["files"] for path in result["paths"]}
    assert sides["straight"] == ("waived", "waived")


def test_a_report_that_cannot_be_written_says_the_answer_then_why_exit_3(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The campaign is complete when the report stage fails (a folder where a figure goes, a
    full disk): its answer is said, then why the report is missing and how to write it; the
    exit code is the failure's (3), never a traceback."""
    from idefix_rules.campaign import runner

    def broken(*args: object, **kwargs: object) -> None:
        raise IsADirectoryError(21, "Is a directory", "out/risk_map_all.png")

    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(runner, "write_report", broken)
    assert main(["campaign.yaml", "--runs", "2", "--quiet"]) == 3
    output = " ".join("".join(capsys.readouterr()).split())
    assert "Traceback" not in output and "Decision:" in output
    assert "error: the report could not be written: IsADirectoryError" in output
    assert "(exit code 1 without the report's failure)" in output
    assert "idefix-verify report" in output
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["exit_code"] == 1


def test_a_waiver_matching_nothing_is_in_summary_json_and_junit_not_only_on_stderr(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Exit 2 for a waiver that matches nothing: CI's files say why (summary.json `problems`,
    a JUnit case in error), not only the console."""
    import xml.etree.ElementTree as ET

    waiver = ("waivers:\n  - {rule: acceptable_risk, path: straight, reason: \"x\", "
              "approved_by: \"me\", until: 2099-01-01}\n")
    materialise(tmp_path, campaign(append=waiver), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(["campaign.yaml", "--runs", "40", "--quiet", "--no-report",
                 "--junit", "junit.xml"]) == 2
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["exit_code"] == 2
    assert [problem["code"] for problem in summary["problems"]] == ["C215"]
    root = ET.parse(tmp_path / "junit.xml").getroot()
    assert root.get("errors") == "1"
    (error_element,) = [e for e in root.iter("error") if e.get("type") == "C215"]
    assert "waiver" in (error_element.get("message") or "")
    for suite in root.iter("testsuite"):  # each suite's time is the sum of its cases'
        cases = sum(float(case.get("time", "0")) for case in suite.iter("testcase"))
        assert abs(float(suite.get("time", "0")) - cases) < 5e-4, suite.get("name")


def test_a_new_run_or_evaluation_sets_the_earlier_report_and_its_figures_aside(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Outputs never speak for another run: a run without a report, or `evaluate`, leaves
    no report page or figure of the earlier one in place (they become *.previous.*); every
    figure the report writes is one of files.REPORT_FIGURES."""
    import fnmatch

    from idefix_rules.files import REPORT_FIGURES

    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    assert main(["campaign.yaml", "--runs", "2", "--quiet"]) == 1
    figures = sorted(path.name for path in out.glob("*.png"))
    assert figures and (out / "report.html").is_file()
    assert all(any(fnmatch.fnmatch(name, pattern) for pattern in REPORT_FIGURES)
               for name in figures), figures
    assert main(["campaign.yaml", "--runs", "2", "--quiet", "--no-report"]) == 1
    assert not (out / "report.html").exists()
    assert all(".previous." in path.name for path in out.glob("*.png"))
    assert (out / "report.previous.html").is_file()
    assert main(["campaign.yaml", "--runs", "2", "--quiet"]) == 1  # a report again
    assert main(["evaluate", "out/results.h5", "--quiet"]) == 1
    assert not (out / "report.html").exists()
    assert all(".previous." in path.name for path in out.glob("*.png"))


def test_the_report_after_evaluate_rulebook_draws_with_that_rulebook(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`evaluate --rulebook NEW` stores NEW's text with its evaluation; `report` then draws
    its limits and maps with NEW, not with the campaign's rulebook."""
    import h5py

    from idefix_rules.report.prepare import setup_from_store
    from idefix_rules.results.reader import StoredResults

    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(list(RUN)) == 1
    changed = tmp_path / "changed.rules"
    changed.write_text((tmp_path / "test.rules").read_text().replace(
        "critical_slip = 70 %", "critical_slip = 60 %"))
    assert "critical_slip = 60 %" in changed.read_text()
    assert main(["evaluate", "out/results.h5", "--rulebook", str(changed), "--quiet"]) == 1
    with h5py.File(tmp_path / "out" / "results.h5") as file:
        assert "critical_slip = 60 %" in file["evaluation/rulebook_text"][()].decode()
    store = StoredResults.open(tmp_path / "out" / "results.h5")
    try:
        setup = setup_from_store(store)
        assert setup.checked is not None
        assert setup.checked.constants["critical_slip"] == pytest.approx(0.6)
    finally:
        store.close()


def test_an_evaluated_interrupted_campaign_says_how_many_runs_it_simulated(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Its stop reason says the runs simulated of those planned, not 'fixed run count', also
    for a path none of whose runs were simulated."""
    from idefix_rules.campaign.storage.store import STATUS_MISSING

    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(["campaign.yaml", "--runs", "4", "--quiet", "--no-report"]) == 1
    results = tmp_path / "out" / "results.h5"
    with h5py.File(results, "r+") as file:  # as a kill after two runs of straight leaves it
        file.attrs["state"] = "interrupted"
        for name, kept in (("straight", 2), ("arc", 0)):
            file[f"paths/{name}/runs/status"][kept:] = STATUS_MISSING
            for signal in file[f"paths/{name}/runs/signals"].values():
                signal[kept:] = np.nan
    assert main(["evaluate", str(results), "--quiet"]) == 1
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    paths = {path["name"]: path for path in summary["paths"]}
    for name, kept in (("straight", 2), ("arc", 0)):
        assert paths[name]["stop_reason"] == (f"interrupted: {kept} of the 4 planned runs "
                                              "simulated (the others count as failed)")
        assert paths[name]["missing_runs"] == 4 - kept


def test_evaluate_records_the_rulebook_absolute_as_it_records_the_results(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main(list(RUN)) == 1
    summary_file = tmp_path / "out" / "summary.json"
    assert main(["evaluate", "out/results.h5", "--rulebook", "test.rules", "--quiet"]) == 1
    summary = json.loads(summary_file.read_text())
    assert summary["rulebook"]["path"] == str((tmp_path / "test.rules").resolve())
    assert main(["evaluate", "out/results.h5", "--quiet"]) == 1
    summary = json.loads(summary_file.read_text())
    assert summary["rulebook"]["path"] == \
        f"{(tmp_path / 'out' / 'results.h5').resolve()}:/provenance/rulebook"


def test_junit_into_a_missing_folder_creates_it_as_out_does_and_explain_error_says_so(
        tmp_path: Path, cli_toy_fmu: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """C207's explanation named a missing folder as its cause, but a CI maintainer's
    `--junit reports/ci/junit.xml` gets its folders made, as `--out` does."""
    materialise(tmp_path, campaign(), cli_toy_fmu)
    monkeypatch.chdir(tmp_path)
    assert main([*RUN, "--junit", "reports/ci/junit.xml"]) == 1  # the toy's paths: undecided
    assert (tmp_path / "reports" / "ci" / "junit.xml").read_text().startswith("<?xml")
    capsys.readouterr()
    assert main(["explain-error", "C207"]) == 0
    explained = " ".join(capsys.readouterr().out.split())
    assert "folder missing" not in explained
    assert "A missing folder is no mistake: it is created, as `--out`'s is" in explained
