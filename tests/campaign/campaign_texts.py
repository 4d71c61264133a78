"""The small campaign and rulebook the campaign tests share (imported by name: a
``conftest`` import would pick whichever tests folder came first)."""

RULEBOOK = """\
rulebook "campaign-test" version "0.1.0"
purpose "Small rulebook for the campaign runner tests"

const critical_slip = 70 %
  because "Slip above 70 % is critical"

settings {
  theoretical_slip = 10 %
  tolerance_growth = 5 cm/rad
}

command wheel_rate_limit: require abs(max_wheel_rate) <= 0.2 rad/s
  because "Fastest wheel rate the locomotion can drive"

index I_pos "position drift" {
  value  = final over time (global_error / tolerance_radius)
  limit  = 1
  weight = 1
  because "Eq. 3"
}

index I_s "wheel slip ratio" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = critical_slip
  weight = 1
  because "Slip"
}

chance slipped = max over time (max over wheels (abs(wheel.slip))) > 30 %
  because "Runs with more than 30 % slip"

prescreen reference_not_critical: require risk < 1
  because "Nominal run must not be critical"

verdict acceptable_risk: require risk <= 50 %
  because "Mean risk limit"
verdict runs_complete: require failed <= 0 %
  because "Every run must finish"

rank by risk, time, energy
"""

CAMPAIGN = """\
name: toy
fmu:
  path: toy.fmu
rulebook: test.rules
output: out
runs: 6
workers: 2
uncertainty:
  method: monte_carlo
  seed: 5
  parameters:
    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}
    initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}
    toy.slip: {distribution: uniform, low: 0.05, high: 0.25}
paths:
  straight:
    - {max_wheel_rate: "0.1 rad/s", delta_position: "0.1 m", delta_heading: "0 deg"}
  arc:
    - {max_wheel_rate: "0.1 rad/s", delta_position: "0.1 m", delta_heading: "20 deg"}
    - {max_wheel_rate: "0.1 rad/s", delta_position: "0.05 m", delta_heading: "-20 deg"}
  too-fast:
    - {max_wheel_rate: "0.5 rad/s", delta_position: "0.1 m", delta_heading: "0 deg"}
simulation:
  output_interval: "0.5 s"
  extra_time: "2 s"
"""
