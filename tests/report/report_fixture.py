"""A small synthetic results file in the documented layout (docs/results-format.md).

Imported by the report tests as ``report_fixture`` (a unique module name: every test folder
has its own ``conftest``, so importing from ``conftest`` would find another folder's).
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from idefix_rules.commands import Command, RoverGeometry, command_kinematics, ideal_poses

RULEBOOK = """\
rulebook "report-test" version "0.1.0"
purpose "Rules for the report tests"

settings {
  theoretical_slip = 10 %
}

obstacles {
  level L1 below 3 cm  buffer 2 cm
  level L2 below 10 cm buffer 5 cm
  level L3             buffer 10 cm
}

index I_s "wheel slip ratio" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = 70 %
  weight = 1.0
}

index I_roll "roll" {
  value  = max over time (abs(roll))
  limit  = 30 deg
  weight = 0.8
}

verdict acceptable_risk: require risk <= 70 %
"""

CAMPAIGN = """\
name: report-fixture
rulebook: report-test.rules
runs: 4
environment:
  rocks:
    - {x: "0.5 m", y: "-0.26 m", radius: "6 cm", level: L2}
  keep_out:
    - name: crater
      polygon: [["0.8 m", "0.4 m"], ["1.1 m", "0.4 m"], ["1.1 m", "0.7 m"], ["0.8 m", "0.7 m"]]
paths:
  straight:
    - {max_wheel_rate: "0.5 rad/s", delta_position: "1 m", delta_heading: "0 deg"}
  detour:
    - {max_wheel_rate: "0.5 rad/s", delta_position: "0.5 m", delta_heading: "20 deg"}
    - {max_wheel_rate: "0.5 rad/s", delta_position: "0.5 m", delta_heading: "-20 deg"}
"""

PATHS = {
    "straight": (Command(0.5, 1.0, 0.0),),
    "detour": (Command(0.5, 0.5, 0.35), Command(0.5, 0.5, -0.35)),
}
RUNS = 4
DT = 0.5


def _signals(chain: tuple[Command, ...], t: np.ndarray, slip: float, dy: float,
             roll: float) -> dict[str, np.ndarray]:
    rover = RoverGeometry()
    poses = ideal_poses(chain, rover, t, scale=1.0 - slip)
    ends = np.cumsum([command_kinematics(c, rover).duration for c in chain])
    command = np.searchsorted(ends, t, side="right").astype(float)
    command[command >= len(chain)] = -1.0
    samples = t.size
    return {
        "t": t, "x": poses[:, 0], "y": poses[:, 1] + dy, "z": np.full(samples, 0.3),
        "roll": np.full(samples, roll), "pitch": np.zeros(samples), "yaw": poses[:, 2],
        "wheel.slip": np.repeat((slip * t / t[-1])[:, None], 4, axis=1),
        "energy": 0.01 * t, "command": command,
    }


def write_results(target: Path, evaluated: bool = True) -> Path:
    """Two paths × 4 runs; run 3 of ``detour`` failed."""
    rng = np.random.default_rng(7)
    with h5py.File(target, "w", track_order=True) as file:
        file.attrs.update({
            "format": "idefix-results", "format_version": 1, "campaign_name": "report-fixture",
            "campaign_path": "/data/report-fixture.yaml", "campaign_sha256": "c" * 64,
            "package_version": "0.1.0", "fmu_path": "/data/idefix_rover.fmu",
            "fmu_sha256": "f" * 64, "seed": 1, "runs": RUNS, "sampling": "monte_carlo",
            "seed_derivation": "SeedSequence(seed, spawn_key=(path, run))",
            "started": "2026-01-01T00:00:00Z", "resumed": "[]",
            "finished": "2026-01-01T00:01:00Z", "state": "complete", "output_interval": DT,
        })
        provenance = file.create_group("provenance")
        provenance.create_dataset("campaign", data=CAMPAIGN, dtype=h5py.string_dtype())
        rulebook = provenance.create_dataset("rulebook", data=RULEBOOK,
                                             dtype=h5py.string_dtype())
        rulebook.attrs.update({"name": "report-test", "version": "0.1.0",
                               "sha256": "r" * 64, "path": "/data/report-test.rules"})
        summary_paths = []
        for index, (name, chain) in enumerate(PATHS.items()):
            duration = sum(command_kinematics(c, RoverGeometry()).duration for c in chain)
            t = np.arange(0.0, duration * 1.3 + DT / 2, DT)
            group = file.create_group(f"paths/{name}")
            group.attrs.update({"index": index, "status": "simulated", "reason": "",
                                "stop_time": float(t[-1]), "samples": t.size,
                                "ideal_duration": duration})
            group.create_dataset("chain", data=np.array([[c.max_wheel_rate, c.delta_position,
                                                          c.delta_heading] for c in chain]))
            reference = group.create_group("reference")
            reference.attrs.update({"status": 1, "failure": ""})
            for key, values in _signals(chain, t, 0.1, 0.0, 0.0).items():
                reference.create_dataset(f"signals/{key}", data=values)
            slips = rng.uniform(0.05, 0.6, RUNS)
            offsets = rng.normal(0.0, 0.02, RUNS)
            rolls = rng.uniform(0.0, 0.3, RUNS)
            status = np.ones(RUNS, dtype=np.int8)
            if name == "detour":
                status[3] = 2
            runs = [_signals(chain, t, s, d, r) for s, d, r in zip(slips, offsets, rolls,
                                                                    strict=True)]
            for key in runs[0]:
                stacked = np.stack([run[key] for run in runs])
                stacked[status != 1] = np.nan
                group.create_dataset(f"runs/signals/{key}", data=stacked)
            group["runs"].attrs["count"] = RUNS
            group.create_dataset("runs/parameters/soil.slip_scale", data=slips)
            group.create_dataset("runs/parameters/initial.y", data=offsets)
            group["runs/parameters/initial.y"].attrs["unit"] = "m"
            group.create_dataset("runs/status", data=status)
            group.create_dataset("runs/failure", data=np.array(
                [b"" if s == 1 else b"the simulation process crashed (SIGSEGV)"
                 for s in status], dtype="S240"))
            if not evaluated:
                continue
            i_s = np.where(status == 1, np.clip(slips / 0.7, 0, 1), np.nan)
            i_roll = np.where(status == 1, np.clip(rolls / np.deg2rad(30), 0, 1), np.nan)
            i_max = np.fmax(i_s, 0.8 * i_roll)
            evaluation = group.create_group("evaluation")
            evaluation.attrs["index_names"] = json.dumps(["I_s", "I_roll"])
            evaluation.create_dataset("indices/I_s", data=i_s)
            evaluation.create_dataset("indices/I_roll", data=i_roll)
            evaluation.create_dataset("i_max", data=i_max)
            evaluation.create_dataset("dominant", data=np.where(
                status == 1, np.where(i_s >= 0.8 * i_roll, 0, 1), -1).astype(np.int16))
            evaluation.create_dataset("time", data=np.full(RUNS, duration))
            evaluation.create_dataset("energy", data=np.full(RUNS, 0.01 * duration))
            evaluation.create_dataset("chances/collision.L2",
                                      data=(np.arange(RUNS) == 0).astype(np.int8))
            evaluation.attrs["statistics"] = json.dumps({})
            evaluation.attrs["verdict"] = json.dumps({"passed": True, "decided": True})
            ok = status == 1
            summary_paths.append({
                "name": name, "index": index, "status": "simulated", "reason": "",
                "runs": RUNS, "completed_runs": int(ok.sum()), "failed_runs": int((~ok).sum()),
                "mean_risk": float(np.mean(i_max[ok])),
                "risk_ci95": [float(np.mean(i_max[ok])) - 0.1, float(np.mean(i_max[ok])) + 0.1],
                "chances": {"collision.L1": 0.0, "collision.L2": 0.25, "collision.L3": 0.0},
                "energy_mAs": 10.0 * duration, "time_s": duration, "dominant_index": "I_s",
                "verdict": "pass" if name == "detour" else "fail", "undecided": name == "detour",
                "verdict_reasons": [f"acceptable_risk <script>alert('{name}')</script>"],
                "rank": index + 1,
            })
        rejected = file.create_group("paths/too-sharp")
        rejected.attrs.update({"index": len(PATHS), "status": "rejected",
                               "reason": "max_turn_angle: command 1 turns 120 deg > 90 deg",
                               "stop_time": 0.0, "samples": 0, "ideal_duration": 0.0})
        rejected.create_dataset("chain", data=np.array([[0.5, 0.1, 2.1]]))
        summary_paths.append({"name": "too-sharp", "index": len(PATHS), "status": "rejected",
                              "reason": "max_turn_angle: command 1 turns 120 deg > 90 deg",
                              "runs": 0, "completed_runs": 0, "failed_runs": 0,
                              "mean_risk": None, "risk_ci95": None, "chances": {},
                              "energy_mAs": None, "time_s": None, "dominant_index": None,
                              "verdict": "rejected", "undecided": False,
                              "verdict_reasons": [], "rank": None})
        if evaluated:
            root = file.create_group("evaluation")
            root.attrs.update({"rulebook_name": "report-test", "rulebook_version": "0.1.0",
                               "rulebook_sha256": "r" * 64, "rulebook_path": "x.rules",
                               "evaluated": "2026-01-01T00:02:00Z",
                               "ranking": json.dumps(["straight", "detour"])})
            root.attrs["summary"] = json.dumps({
                "format": "idefix-summary", "format_version": 1, "paths": summary_paths,
                "ranking": ["straight", "detour"],
                "expectations": [{"description": "detour passes", "held": True,
                                  "message": "ok"}]})
    return target


