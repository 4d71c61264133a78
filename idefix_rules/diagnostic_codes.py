"""Every diagnostic code, with a long explanation, an example of the mistake and its fix.

``idefix-verify explain-error CODE`` prints an entry; ``docs/testing-rulebooks.md`` and the
other docs list the codes by area. Codes by range: C campaigns, D diff, E0xx–E5xx rulebooks,
E6xx obstacles, E7xx evaluation inputs, F FMU and terrain, H results files, T case files,
W6xx warnings of ``check --strict``. The table below is data: ``CODE|title|explanation|example
of the mistake|the fix`` per line, ``\\n`` for a line break.

>>> explain("W610").title
'ratio written as a bare number above 1'
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Explanation:
    code: str
    title: str
    explanation: str
    example: str
    fix: str

    def render(self) -> str:
        """Plain text for the terminal."""
        example = "\n".join("    " + line for line in self.example.splitlines())
        return (f"{self.code}: {self.title}\n\n{self.explanation}\n\nFor example:\n"
                f"{example}\n\nFix: {self.fix}")


_TABLE = r"""
C000|invalid YAML|The campaign file is not well-formed YAML: the parser stopped at the marked line and column (an unclosed bracket, a tab used for indentation, a key without a colon).|paths: {straight: [|Close every bracket and indent with spaces: `paths: {straight: [...]}`.
C001|mapping keys must be plain names|A YAML key is itself a list or a mapping (`? [a, b]: 1`); campaign keys are plain names.|? [x, y]: 1 cm|Write one key per line: `x: 1 cm`.
C002|duplicate key|The same key appears twice in one mapping; YAML would silently keep the last one, so the campaign refuses it.|runs: 100\nruns: 200|Keep one `runs:` line.
C003|the document expands to too many values|YAML aliases (`*name`) copy whole anchored blocks; nested aliases multiply ("billion laughs"). A campaign expanding past 100 000 values is refused instead of exhausting memory.|a: &a [1, 1]\nb: &b [*a, *a]\n# … ten levels deeper|Write the values out, or reference a file instead of copying blocks.
C004|YAML tag not allowed|Tags such as `!!python/object` could make a loader run code; campaign files are loaded safely and refuse every non-standard tag.|fmu: !!python/object:os.system ls|Write the plain value: `fmu: ../fmu/idefix.fmu`.
C010|campaign file missing, unreadable or not UTF-8|The campaign file named on the command line does not exist, is a folder, cannot be read, or holds bytes that are not UTF-8 (the first bad byte is located).|idefix-verify campaings/rock-detour.yaml|Check the path (`ls campaigns/`) and save the file as UTF-8.
C100|campaign value invalid|A campaign field has the wrong type, a missing unit, a value out of range or an unknown name; the message names the field (`paths.detour[1].delta_heading`). Numbers are written with the ASCII digits 0-9 (`"７0 %"` is refused at the `７`), a nonzero number too small for a double (`1e-400`, which would be read as 0) is refused, and a seed lies in 0 … 2^64 - 1.|delta_heading: 30|Give the quantity with its unit: `delta_heading: "30 deg"`.
C101|a campaign file is a mapping|The top level of a campaign must be `key: value` lines (name, rulebook, paths …), not a list or a single value.|- straight|Start from `campaigns/rock-detour.yaml` and keep its `key: value` layout.
C200|file named in the campaign missing|The rulebook, FMU or DEM the campaign names (relative to the campaign file) does not exist or is a folder.|rulebook: ../rulebooks/ops.rules|Name the existing file, relative to the campaign: `rulebook: ../rulebooks/idefix-ops.rules`.
C201|workers invalid|`workers:` must be `auto` or a positive whole number of processes.|workers: 0|`workers: auto` (one per core) or `workers: 2`.
C202|expectation names an unknown path|An entry of `expect:` refers to a path that the campaign's `paths:` does not declare.|expect:\n  - {passes: [stright]}|Use a declared path name: `passes: [straight]`.
C203|DEM holds heights only|A `.npy` or `.csv` DEM has no grid spacing of its own; the campaign must give it.|terrain: {dem: site.npy}|Add the spacing: `terrain: {dem: site.npy, cell: "2 cm"}`.
C204|terrain file gives its own geometry|A terrain file (`.terrain`) carries its cell size and origin; giving them again in the campaign is ambiguous.|terrain: {dem: site.terrain, cell: "2 cm"}|Remove `cell` (only `.npy` and `.csv` DEMs take one).
C205|output folder cannot be used|The output folder is a file, lies below a file, or cannot be created or written.|output: results.h5|Name a folder that can be created: `output: ../results/rock-detour`.
C206|rock outside the terrain|A rock of `environment.rocks` lies outside the terrain grid, so the rover model could never meet it.|rocks: [{x: "9 m", y: 0 m, radius: "4 cm"}]|Move the rock inside the terrain, or enlarge `terrain.size`.
C207|cannot write the JUnit file|`--junit FILE` could not be written (folder missing, no permission); the results themselves are stored.|idefix-verify c.yaml --junit /root/out.xml|Write the report where you may: `--junit build/junit.xml`.
C209|named area not declared or misplaced|`environment.areas` gives the geometry of the areas the rulebook declares (`area NAME KIND level L buffer B` in its obstacles block): a name the rulebook does not declare, polygons for a steep area (found in the terrain from the rulebook's inclination) or a polygon without area is an error at its line.|areas: {craters: {polygons: [...]}}  # the rulebook declares 'crater'|`areas: {crater: {polygons: [[["1 m", "0 m"], ["2 m", "0 m"], ["2 m", "1 m"]]]}}`.
C210|named area without polygons|The rulebook declares a keep-out or unknown-surface area the campaign gives no polygons for: its `area.NAME.*` signals are 0 in every run (a warning, so a rulebook can declare areas that some sites do not have).|the rulebook declares 'crater'; the campaign has no environment.areas.crater|`environment: {areas: {crater: {polygons: [...]}}}`, or `crater: {polygons: []}` to say the site has none.
C211|waiver names an unknown rule|A `waivers:` entry's `rule` is neither a verdict, a prescreen nor a command rule of the campaign's rulebook. Checked before anything is simulated (exit 2).|waivers: [{rule: acceptable_rsk, ...}]|Name a rule the rulebook declares: `rule: acceptable_risk` (`idefix-verify explain RULEBOOK` lists them).
C212|waiver names an unknown path|A `waivers:` entry's `path` is not a path of the campaign's `paths:` (nor `all`).|waivers: [{rule: acceptable_risk, path: stright, ...}]|Name a declared path, or `path: all` (the default).
C213|waiver expired|Today is after the waiver's `until` date (the day itself is still valid). An expired waiver is refused rather than silently dropped, so a plan never fails or passes by a date nobody looked at. Checked by a run and again by `evaluate`, against the day it is run: a stored campaign's waiver expires too (renew it in the campaign file and run the campaign again).|until: 2025-01-31|Renew it with a new date (approved again) or remove it.
C214|command rule waived without command_rules: true|A chain that breaks a command rule is rejected before Monte Carlo; a waiver lets it through only when it says so explicitly with `command_rules: true`.|waivers: [{rule: wheel_rate_limit, path: fast, ...}]|Add `command_rules: true` to the waiver if the chain may really be sent with that command, else remove it.
C215|waiver matches nothing|After the evaluation, a waiver's rule held on every path it names (or the path never reached the rule: a verdict waiver of a rejected path). The results, summary.json and JUnit are written; the exit code is 2 whatever else happened (3 stays 3).|a waiver of `runs_complete` on a path whose runs all completed|Remove the waiver: a waiver is for a failure that happens.
C216|rover starts off the terrain|The rover's nominal start (`initial.x`, `initial.y`) lies outside the terrain grid given to the FMU: it would drive on the edge heights carried on.|initial.x: {distribution: normal, mean: "50 m", std: "1 cm"} on a 4 m terrain|Give the start in the terrain's frame, or a terrain that holds it.
C208|output folder in use|Another campaign (or `evaluate`) owns the output folder: its lock file `.idefix.lock` names the owner's pid, host, start time and command. Two campaigns writing one folder would replace each other's results and summary. A lock whose owner ran on this host and no longer runs (killed with `kill -9`, a crash, a reboot) is stale and taken over with a note; one from another host cannot be checked and is refused.|idefix-verify c.yaml   # while another `idefix-verify c.yaml` still runs|Wait until the other campaign ends, or give this one its own folder: `--out results/second`. If the owner is on another host and no longer runs, delete the `.idefix.lock` the message names.
C400|not a usable FMU|The FMU is not a readable zip with a modelDescription.xml, or it is not an FMI 2.0 co-simulation FMU (FMI 3.0 or model exchange only).|fmu: idefix-me.fmu  # model exchange|Export the model as FMI 2.0 co-simulation, or build ours: `idefix-verify build-fmu`.
C401|unknown FMU variable|A name in the campaign's signal or parameter map does not exist in the FMU; the hint lists close names.|signals: {x: body.pos_x}|Use the variable name from `fmpy info model.fmu`: `signals: {x: body.x}`.
C402|FMU variable has the wrong unit|A mapped variable's unit (from modelDescription.xml) has another dimension than the contract signal or parameter it is mapped to.|signals: {roll: body.x}  # m, not rad|Map a variable of the right dimension: `signals: {roll: body.roll}`.
C403|chain longer than the FMU takes|The FMU holds the chain in fixed-size arrays (`chain.max_wheel_rate[0] … [N-1]`); a path has more commands than that.|paths: {long: [... 40 commands ...]}|Split the path into shorter chains, or rebuild the FMU with a larger chain capacity.
C404|a run would be too long|Stop time divided by the output interval would give more than 1 000 000 samples per run.|output_interval: "1 ms"|Sample less often (`output_interval: "0.1 s"`) or shorten the chain.
C405|signal map lacks a signal the rulebook reads|The rulebook reads a signal (e.g. `wheel.sinkage`) that the campaign's `fmu.signals` map does not provide.|signals: {x: body.x, y: body.y}|Map every signal the rulebook reads: add `wheel.sinkage: wheels.sinkage`.
D001|not a git revision|`PATH@REV` names a revision git does not know.|idefix-verify diff rules.rules@HAED~1 rules.rules|Use an existing revision: `rules.rules@HEAD~1` (see `git log -- rules.rules`).
D002|folder of PATH@REV not found|The folder of `PATH` must exist in the working tree, because git is asked from there.|diff old/ops.rules@v1 rulebooks/ops.rules|Give the path as it is in the working tree: `rulebooks/ops.rules@v1`.
D003|git missing or too slow|`PATH@REV` needs git; it is not installed or did not answer in time.|diff ops.rules@HEAD~1 ops.rules  # on a machine without git|Install git, or compare two files: `git show HEAD~1:ops.rules > old.rules`.
D004|file not in that revision|git knows the revision but the file did not exist there (or was elsewhere).|diff rulebooks/ops.rules@v0.1 rulebooks/ops.rules|Check `git log -- PATH` for the revisions that have the file.
D010|stored campaign cannot be read back|`diff --results` re-scores a results file, which stores its campaign; that campaign no longer validates (e.g. its FMU moved).|diff a.rules b.rules --results old/results.h5|Re-run the campaign, or restore the files it names.
D020|bad diff option|`--top` must be 0 or more, `--chunk-runs` and `--threads` at least 1.|diff a.rules b.rules --chunk-runs 0|`--chunk-runs 128`.
E000|invalid input|The input is not text, or not what the command expects at all.|idefix-verify check picture.png|Give a rulebook (`.rules`) text file.
E001|syntax error|The parser met a token it did not expect; the message says what it expected instead. Several syntax errors are reported in one run.|verdict acceptable_risk: require risk = 70 %|Compare with `==` or `<=`: `require risk <= 70 %`.
E002|rulebook file missing or unreadable|The rulebook file does not exist, is a folder, cannot be read, or is not UTF-8.|idefix-verify check rulebooks/idefix-op.rules|Check the path: `rulebooks/idefix-ops.rules`.
E003|number outside a double's range|A number does not fit a double: above about 1.8e308 it would be infinite, and a nonzero number below about 5e-324 would be read as 0 (a number that only its unit's scale takes below, `5e-324 mm`, is warning W613 of `check --strict`: `fmt` prints every double so that it reads back).|const huge = 1e999 m\nconst tiny = 1e-400 %|Use a finite value and a fitting unit: `const huge = 1 km`; write `0 %` if zero is meant.
E004|section appears twice|`settings`, `obstacles`, `combine`, `rank by` and the header may appear once each.|settings { tolerance_growth = 5 cm/rad }\nsettings { theoretical_slip = 20 % }|Merge them: `settings { tolerance_growth = 5 cm/rad  theoretical_slip = 20 % }`.
E006|index item missing or repeated|Every index needs exactly one `value`, `limit` and `weight`, and gives `nominal`, `map` and `because` at most once.|index I_s "slip" { value = max over time (wheel.slip[FL]) weight = 1 }|Add the limit: `limit = 70 %`.
E007|unknown domain after over|Reductions run over `time`, `wheels`, `parts` or `levels`.|max over wheel (wheel.slip)|`max over wheels (wheel.slip)`.
E008|unknown combination|`combine` knows `run = max_weighted` and `path = mean` (the paper's equations 1 and 2).|combine { run = sum }|`combine { run = max_weighted  path = mean }`.
E009|too many syntax errors|After many syntax errors the parser stops: later ones are probably follow-ups of the first.|(a file with dozens of broken lines)|Fix the first errors and check again.
E010|fmt cannot write the file|`idefix-verify fmt` could not write the formatted text back; the file is left as it was.|idefix-verify fmt /read-only/ops.rules|Make the file writable, or print to the terminal with `fmt --diff`.
E011|number written with other digits than 0-9|Numbers are written with the ASCII digits 0-9. A digit of another script (full-width `７`, Arabic-Indic `٣`, Devanagari `७` …) looks like a number, and Python would read it as one, but a reader or another tool may not: it is refused at its column, with the number written in ASCII as the hint.|const critical_slip = ７0 %|`const critical_slip = 70 %` (switch the input method back to half-width digits).
E101|unknown name|A name is not declared, or not visible where it is used (each context sees different names; see "names per context"). A verdict that names an index or chance is told to use its path statistic.|verdict slip_ok: require I_s < 50 %|Use the path statistic: `require mean(I_s) < 50 %`.
E102|declared twice|Every constant, rule, index and chance has one name in one namespace.|const limit = 5 cm\nconst limit = 6 cm|Keep one, or rename: `const limit_rocks = 6 cm`.
E103|declaration hides a built-in name|A declared name equals a signal or a built-in name of a context (`speed`, `risk`, `stuck`).|chance stuck = any over time (stuck > 0)|Choose another name: `chance got_stuck = any over time (stuck > 0)`.
E104|unknown label or level|A label (`FL`, `L2`, `chassis`) does not exist, or the selected expression has no such axis.|wheel.slip[FX]|`wheel.slip[FL]` (wheels FL FR RL RR; parts wheel solar_panel chassis; levels L1 L2 L3).
E105|unknown function|Functions are `abs`, `min`, `max`, `sqrt`, `clamp`, and in verdicts `chance`, `mean`, `max`.|require avg(speed) < 1 cm/s|Use a reduction: `mean over time (speed) < 1 cm/s`.
E106|wrong number of arguments|A function got too many or too few arguments, or a reducer's parameter is missing or not allowed.|percentile over time (speed)|Give the parameter: `percentile 95 over time (speed)`.
E201|dimensions do not match|Two quantities of different dimensions are added, compared or mixed. In a constant the error is reported once, at the definition, with the places that use it.|const critical_slip = 70 cm + 3 deg|Keep one dimension: `const critical_slip = 70 %`.
E202|invalid power or root of a dimension|A dimension can only be raised to a whole number power (and `sqrt` needs even exponents).|const x = (5 cm) ^ 0.5|Write the intended unit directly, or square and root whole dimensions.
E204|wrong dimension|A limit, nominal, setting, window or obstacle size has another dimension than its place needs (an index's limit and nominal have its value's dimension). A constant that is wrong for every place using it is reported once, at its definition, with the uses as notes.|index I_ds "sinkage" { value = max over time (wheel.sinkage[FL]) limit = 5 deg weight = 1 }|`limit = 5 cm`.
E205|unknown unit|The unit after a number is not one of the language's units (docs/rulebook-language.md, units).|const max_speed = 1 cm/sec|`const max_speed = 1 cm/s`.
E301|reduction over a missing axis|A reduction runs over an axis its operand does not have, or a time-only reducer runs over another axis.|max over wheels (pitch)|`max over time (pitch)`; wheels only for per-wheel signals.
E302|value still has axes|One value per run (or per command) is needed, but the expression still varies over time, wheels, parts or levels.|index I_s "slip" { value = wheel.slip[FL] limit = 70 % weight = 1 }|Reduce it: `value = max over time (wheel.slip[FL])`.
E303|a condition is needed|A rule's `require` (and a chance) must be a comparison or a combination of comparisons.|command speed_limit: require speed|`command speed_limit: require abs(speed) <= 1 cm/s`.
E304|a quantity is needed|A condition stands where a number is needed (index value, constant, rank key).|index I_x "x" { value = max over time (speed) > 1 cm/s limit = 1 weight = 1 }|Make it a chance, or drop the comparison: `value = max over time (speed)`.
E305|window on a reduction not over time|`during`, `after`, `before` select samples; they only apply to reductions over time.|max over wheels after 10 s (wheel.slip)|`max over time after 10 s (max over wheels (wheel.slip))`.
E306|malformed table|A table names every label of one axis exactly once, with plain quantities of one dimension.|const f_obs = {L1: 0.2, L2: 0.6}|`const f_obs = {L1: 0.2, L2: 0.6, L3: 1}`.
E307|malformed map|An index's `map` is one quantity per sample (a time series) with the dimension of its value.|map = max over time (speed)|`map = speed` (keep the time axis).
E309|rate of change with a window or not over time|`rate over time (x)` is x's rate of change at every sample: it keeps the time axis, so it runs over time only and takes no window; reduce it with the window you need.|max over time (rate over time after 10 s (wheel.sinkage))|`max over time after 10 s (rate over time (wheel.sinkage))`.
E308|percentile outside 0–100|`percentile P` takes P from 0 (the smallest sample) to 100 (the largest).|percentile 150 over time (speed)|`percentile 95 over time (speed)`.
E401|weight outside [0, 1]|Weights scale normalised indices in eq. 1 and lie in [0, 1].|weight = 2|`weight = 1`.
E402|value out of range|A negative buffer or setting, a limit not above zero, a theoretical slip of 100 % or more, or a constant that is not finite (a division by zero).|limit = 0 cm|A positive limit: `limit = 5 cm`.
E403|constants depend on each other in a circle|A constant's value reads itself through other constants.|const a = b * 2\nconst b = a / 2|Give one of them a value: `const b = 5 cm`.
E409|malformed area|A named area (`area NAME KIND level L buffer B`) is declared once, names a level L1–L3 and a buffer that is not negative; a steep area starts at an inclination above 0° and below 90°.|area scarp steep above 95 deg level L3 buffer 5 cm|`area scarp steep above 20 deg level L3 buffer 5 cm`.
E405|obstacle levels incomplete or out of order|L1, L2 and L3 must all be declared, with increasing size thresholds; only L3 omits `below`.|level L1 below 10 cm buffer 2 cm\nlevel L2 below 3 cm buffer 5 cm|`level L1 below 3 cm …` then `level L2 below 10 cm …`.
E406|confidence outside [50 %, 100 %)|The confidence level of verdict intervals lies in [50 %, 100 %).|confidence = 100 %|`confidence = 95 %`.
E410|indifference outside [0 %, 50 %)|`combine { indifference = … }` is the margin on the difference of two paths' mean risks within which they are tied (share a rank); a ratio from 0 % (no ties) up to, not including, 50 %.|combine {\n  indifference = 60 %\n}|`indifference = 2 %`.
E411|a verdict's indifference of the wrong dimension|`verdict NAME: require CONDITION indifference MARGIN` gives the margin around the limits the verdict compares statistics with: a statistic confidently within it of its limit is *marginal* (neither shown to pass nor to fail). The margin has the dimension of what the verdict compares (a ratio for a chance or the risk, a duration for `time`); a verdict comparing quantities of different dimensions cannot have one margin.|verdict quick: require time <= 10 min indifference 2 %|`indifference 30 s`, or split the verdict so that each compares one kind of quantity.
E412|indifference margin out of range|A verdict's `indifference` is a finite margin of 0 or more; `combine { verdict_indifference = … }`, the margin of every verdict on ratios that gives none of its own, lies in [0 %, 50 %).|verdict rare_hits: require chance(hit_L3) <= 5 % indifference -1 %|`indifference 1 %` (or 0 % for no margin).
E407|nominal not above zero|An index's `nominal` is the value expected in the environment; the index is 0.5 there (paper, section 3.2: "values of around 0.5 represent the expected risk"). Its normalisation runs through (0, 0), (nominal, 0.5) and (limit, 1), so a nominal of 0 or below has no meaning.|index I_s {\n  value   = max over time (max over wheels (abs(wheel.slip)))\n  nominal = 0 %\n  limit   = 70 %\n  weight  = 1\n}|A nominal between 0 and the limit: `nominal = 20 %`; or leave `nominal` out for `value / limit`.
E408|nominal not below the limit|An index's `nominal` (0.5 on its scale) must lie below its `limit` (1 on its scale), both in SI: a nominal at or above the limit would make the index fall while the value grows.|index I_s {\n  value   = max over time (max over wheels (abs(wheel.slip)))\n  nominal = 80 %\n  limit   = 70 %\n  weight  = 1\n}|Swap them or correct one: `nominal = 20 %`, `limit = 70 %`.
E500|no header|A rulebook starts with `rulebook "NAME" version "X.Y.Z"` and `purpose "…"`.|const a = 1 cm|`rulebook "ops" version "1.0.0"` and `purpose "Movement rules …"` first.
E501|no index|A rulebook needs at least one risk index (eq. 1 has nothing to combine otherwise).|(a rulebook with command rules only)|Add `index I_s "slip" { value = … limit = … weight = 1 }`.
E502|no verdict rule|A path passes when every verdict holds; without one nothing is decided.|(a rulebook without `verdict`)|Add `verdict acceptable_risk: require risk <= 70 %`.
E503|version is not a semantic version|Versions are `MAJOR.MINOR.PATCH` so diffs can tell which is newer.|version "1.0"|`version "1.0.0"`.
E504|empty name or purpose|The header's name and purpose are shown in every report and diff.|purpose ""|`purpose "Movement rules for manual driving"`.
E505|unknown setting|`settings` knows `theoretical_slip` and `tolerance_growth`.|settings { tolerance = 5 cm/rad }|`settings { tolerance_growth = 5 cm/rad }`.
E601|rover body dimension invalid|The rover geometry for collision checks needs positive lengths in metres.|body: {chassis_length: -0.4}|`chassis_length: 0.41` (m).
E610|unknown obstacle level|An obstacle names a level other than L1, L2, L3.|rocks: [{x: 1 m, y: 0 m, radius: 4 cm, level: L4}]|`level: L3`.
E611|level thresholds out of order|Size thresholds must satisfy 0 < L1 max size ≤ L2 max size.|thresholds (0.1 m, 0.03 m)|(0.03 m, 0.1 m): the rulebook's `obstacles` block gives them in order.
E612|buffer margins invalid|Buffer margins need one finite length ≥ 0 per level L1–L3.|buffer margins (0.02, -0.05, 0.1)|Non-negative margins: `level L2 below 10 cm buffer 5 cm`.
E613|obstacle names not unique|Every obstacle (rock or area) needs its own name so collisions can be reported by name.|two areas both named "crater"|`crater_north`, `crater_south`.
E614|obstacle record malformed|An obstacle record lacks a field or has one of the wrong type (the message names it).|{name: crater, points: 3}|`points: [[0, 0], [1, 0], [0, 1]]`.
E620|DEM too small for a slope|Steep-terrain areas come from slopes of the DEM, which needs at least 2 × 2 heights.|a 1 × 5 height grid|A grid of at least 2 × 2 heights.
E621|slope threshold out of range|The steep-terrain slope threshold lies strictly between 0 and 90 degrees.|max_slope: 95 deg|`max_slope: 25 deg`.
E622|polygon invalid|An area polygon needs at least 3 finite vertices that enclose an area.|points: [[0, 0], [1, 1]]|`points: [[0, 0], [1, 0], [1, 1]]`.
E630|poses lack a coordinate|Collision checks need the pose signals x, y, z, roll, pitch, yaw of every run.|poses without yaw|Provide every pose signal (map `yaw` in the campaign).
E631|poses badly shaped|Pose arrays must all be shaped (runs, samples).|x of shape (100,), y of shape (1, 100)|Give every pose as (runs, samples).
E632|pose not finite|A pose holds NaN or infinite values; the simulator probably failed for that run.|x = [0.1, nan, …]|Check the FMU's run (it should be marked failed), or drop the run.
E701|run signals lack t|Evaluating runs needs the time signal `t`.|evaluate({'x': …}, context)|Include `t` (shape (runs, samples)).
E702|reference signal missing|A rule reads `ref.*`, `global_error`, `drift` or `heading_error`, which need the reference run's signals.|RunContext(chain) without reference|`RunContext(chain, reference={'x': …, 'y': …, 'z': …, 'yaw': …})`.
E703|reference run on another time grid|The reference run's signals must have as many samples as the runs.|reference x of 80 samples, runs of 100|Resample the reference run to the runs' grid.
E704|unknown signal|An evaluation was asked for a signal outside the contract.|source.get('wheel.slipp')|Use a contract name (docs/rulebook-language.md, signals).
E705|signal badly shaped|A signal's array does not have the contract's shape (runs, then its axes).|wheel.slip of shape (runs, samples)|(runs, samples, 4): one column per wheel FL FR RL RR.
F101|FMU file missing|The FMU path does not exist or is a folder.|idefix-verify run c.yaml  # fmu: idefx.fmu|Fix the path, or build ours: `idefix-verify build-fmu`.
F102|not a readable FMU|The file is not a zip with a valid modelDescription.xml.|fmu: model.zip (a plain zip)|Export a real FMU from the modelling tool.
F103|wrong FMI kind|The runner runs FMI 2.0 co-simulation FMUs.|an FMI 3.0 or model-exchange-only FMU|Export as FMI 2.0 co-simulation.
F104|FMU variable missing|A mapped signal or parameter variable does not exist in the FMU.|signals: {x: pos.x}|Use the name `fmpy info model.fmu` lists.
F105|not an fmu signal of the contract|Only `fmu` signals of the contract are read from an FMU (derived and collision signals are computed).|signals: {speed: body.v}|Map `x`, `y`, … and let the evaluator derive `speed`.
F106|parameter value unreadable|A parameter value is not a quantity the runner understands.|soil.cohesion: "lots"|`soil.cohesion: "250 Pa"`.
F107|parameter has the wrong unit|A parameter's value has another dimension than the FMU variable's unit.|soil.cohesion: "250 m"|`soil.cohesion: "250 Pa"`.
F108|Boolean parameter not supported|Boolean FMU parameters cannot be set from a campaign yet.|parameters: {use_gyro: true}|Leave the FMU's default, or expose it as a 0/1 real.
F109|bad simulation timing|The output interval must be above 0 and the stop time at least 0.|output_interval: "0 s"|`output_interval: "0.1 s"`.
F110|FMU rejected a value|The FMU refused a parameter or failed during setup; the message carries its log.|initial.z far outside the terrain|Set the parameter within the allowed range the hint names.
F201|terrain size invalid|A synthetic terrain needs a positive size larger than its cell.|size: "1 cm", cell: "2 cm"|`size: "4 m", cell: "2 cm"`.
F202|too many rocks|The FMU's terrain holds a bounded number of rocks.|a list of 10 000 rocks|Keep the rocks near the paths.
F203|terrain file unreadable|The terrain file named by the campaign exists but cannot be read (permissions, a broken disk, a folder, a `.npy` of Python objects: never loaded).|dem: missing.terrain|Check the path and permissions.
F204|terrain file malformed|The terrain file's header or grid is malformed (the message names its line).|`nx 10` then 9 values per row|Write as many values per row as `nx` says.
F205|DEM needs a cell size|A `.npy` or `.csv` DEM gives heights only; the cell size must be positive.|cell: "0 cm"|`cell: "2 cm"`.
F206|DEM not a finite 2-D grid|A DEM must be a finite 2-D array of at least 2 × 2 heights.|a 1-D array, or one with NaN|Fill holes and give a 2-D grid.
F207|not a number in a CSV DEM|A CSV DEM cell is not a number, or not a finite one (`nan`, `inf`; line and column named).|0.1,0.2,abc|`0.1,0.2,0.3`.
F208|ragged CSV DEM|Every row of a CSV DEM needs as many values as the first.|row 2 has 9 values, row 1 has 10|Give every row the same number of values.
H001|results file not found|The results file named on the command line does not exist (the campaign was not run, or wrote elsewhere).|idefix-verify report results/x/results.h5|Run the campaign first, or fix the path.
H002|results path is a folder|A results file was expected but a folder was given.|idefix-verify report results/rock-detour|`idefix-verify report results/rock-detour/results.h5`.
H003|not an idefix results file|The HDF5 file lacks the groups an idefix results file has (provenance, paths).|idefix-verify report other.h5|Give a results.h5 written by `idefix-verify run`.
H004|damaged results file|A results file whose objects are gone or of the wrong kind, or whose stored data no longer reads back (a chunk that does not inflate), names the object.|a results.h5 cut by a copy that stopped|Run the campaign again to write it anew.
H010|cannot resume a different campaign|`--resume` continues a stored campaign only with the same campaign, runs and seed.|--resume with a changed --runs|Resume with the same settings, or start a new output folder.
H011|stored runs lack a signal|`evaluate --rulebook` re-scores stored runs, which do not hold a signal the new rulebook reads.|a rulebook that now reads wheel.current|Map the signal in the campaign and run it again.
T001|case file unreadable or not YAML|The case file does not exist, cannot be read, is not UTF-8, or is not well-formed YAML (the place is named).|cases: {slip: {signals: {wheel.slip[FL]: 35 %}}}|In flow style quote keys with brackets: `{"wheel.slip[FL]": 35 %}` (or use block style).
T002|case file structure|A case file is a mapping with `rulebook` and `cases`; each case is a mapping and must `expect:` something; `signals`/`offsets` are mappings of signal names to keyframes.|cases:\n  - slip|`cases:\n  slip:\n    signals: …\n    expect: {verdict: fail}`.
T003|case file's rulebook missing|The case file must name its rulebook, relative to the case file, and the file must exist. The rulebook's own errors are reported with their codes.|rulebook: idefix-ops.rules  # in rulebooks/tests/|`rulebook: ../idefix-ops.rules`.
T004|signal cannot be shaped|Only fmu signals (and `collision.clearance`) take keyframes; derived signals (speed, global_error …) follow from them, `command` follows the chain, collisions have their own entry. A label must belong to the signal's axis.|signals: {speed: {0 s: 0, 10 s: 2 cm/s}}|Shape the position instead: `offsets: {x: {10 s: 0 cm, 12 s: 2 cm}}`.
T005|quantity without the right unit|A keyframe value, time, chain parameter or setting needs a unit of the right dimension (bare numbers only for ratios).|roll: {0 s: 0 deg, 20 s: 20}|`roll: {0 s: 0 deg, 20 s: 20 deg}`.
T006|keyframe times not increasing|Keyframe times start at 0 s or later and increase.|roll: {10 s: 0 deg, 5 s: 2 deg}|`roll: {5 s: 2 deg, 10 s: 0 deg}`.
T007|bad chain command|A command of a case's chain is a mapping with `max_wheel_rate`, `delta_position` and `delta_heading`, each with its unit.|chain: [{max_wheel_rate: 0.04 rad/s, delta_position: 20 cm}]|Add `delta_heading: 0 deg`.
T008|expectation names an unknown rule|An expected index, chance, prescreen, command rule or verdict is not declared in the rulebook.|expect: {indices: {I_slip: 0.5}}|`expect: {indices: {I_s: 0.5}}`.
T009|bad expected value|Index and risk expectations are numbers or `{value, tolerance}` / `{at_least, at_most}`; chances `true`/`false`; prescreens and verdicts `pass`/`fail`; `rejected` lists command rules.|expect: {verdict: maybe}|`expect: {verdict: fail}`.
T010|bad collision|A collision names a `part` (wheel, solar_panel, chassis), a `level` (L1–L3) and `at` or `from`/`to` times; `buffer: true` for a buffer zone entry.|collisions: [{part: wing, level: L2, at: 3 s}]|`collisions: [{part: solar_panel, level: L2, at: 3 s}]`.
T011|unknown key|A key of the case file is not part of the format (a typo?).|expectt: {verdict: pass}|`expect: {verdict: pass}`.
T012|bad run count|`runs`, `failed_runs` and each variant's `count` are whole numbers (runs ≥ 1); give either `runs` or `variants`.|runs: 0|`runs: 20`.
T013|no case files found|`idefix-verify test` found no `*.yaml` in the given folders (default `rulebooks/tests`).|idefix-verify test rulebooks/|Put case files in `rulebooks/tests/` or name them.
T014|--min-coverage out of range|`--min-coverage` is a percentage from 0 to 100.|--min-coverage 150|`--min-coverage 100`.
T015|mutation option out of range|`--min-mutation-score` is a percentage from 0 to 100; `--nudge` (how far a threshold, limit or factor is moved by a mutant) a percentage above 0 and below 100.|--mutate --nudge 0|`--mutate --nudge 10` (the default).
W601|constant never used|(`--strict`) A constant no rule reads: a leftover, or a rule that forgot it.|const forgotten = 3 cm|Use it (`limit = forgotten`) or delete it.
W602|index with weight 0|(`--strict`) An index with weight 0 never affects the risk.|weight = 0|Give it a weight (`weight = 1`) or delete the index.
W610|ratio written as a bare number above 1|(`--strict`) A fraction (risk, chance, slip, an index) is compared with, or limited by, a bare number above 1: `70` means 7000 %, not 70 %.|verdict acceptable_risk: require risk <= 70|`require risk <= 70 %` (or `0.7`).
W611|comparison always true or always false|(`--strict`) Over the declared range of what it compares (risk and chances in [0, 1], magnitudes ≥ 0) the comparison can never change its outcome, so the rule decides nothing.|prescreen no_collision: require I_obs <= 1|`require I_obs < 1` (an index reaches 1 at its limit).
W612|rationale disagrees with the value|(`--strict`) The rationale names a number after a comparison word (above, below, limit …) with the value's dimension, but not the value itself: one of them was edited alone.|const critical_slip = 65 % because "Slip above 70 % is critical"|Make them agree: `const critical_slip = 70 % because "Slip above 70 % is critical"`.
C500|not a signal|A key of `fmu.signals` must be a signal of the contract (`x`, `yaw`, `wheel.slip[FL]`, …); a wheel signal needs its wheel, a signal without wheels takes none.|signals: {pos_x: px}|Map to the contract's name: `signals: {x: px}`; `docs/bring-your-own-fmu.md` lists them all.
C501|wrong causality|A signal is read from an output of the FMU; a set-point is fed to an input. The mapped variable is something else (an input, a parameter, a local).|signals: {x: x0}  # x0 is a parameter|Map the output (`fmpy info rover.fmu` lists the outputs and inputs).
C502|type no getter reads|Signals are read from Real/Float, Integer, Boolean or Enumeration outputs (converted to float); set-points are Real (or Integer for `command`). String, Binary and Clock variables cannot be used.|signals: {command: phase_name}  # a String|Map a numeric output, e.g. the phase index.
C503|unit of the wrong dimension|The FMU declares a unit for the variable whose dimension is not the signal's (values are converted to SI from the declared unit, so `mm` for `x` is fine, `deg` is not).|signals: {x: heading}  # heading in deg|Map a variable of that dimension.
C504|parameter not settable|A sampled or fixed parameter must be a parameter or input of the FMU that can be set before the run; an output, a local or a constant cannot.|parameters: {soil.cohesion: c_out}|Map a tunable parameter (`fmpy info` lists them).
C505|parameter of the wrong type|A sampled or regolith value is a number; the FMU parameter it is mapped to is a String or Boolean.|parameters: {soil.cohesion: soil_name}|Map a Real or Integer parameter.
C506|ranking by energy unavailable|The rulebook ranks by energy, but the signal map provides no `energy`; paths equal in the other ranking keys are ranked by name (a warning).|rank by risk, energy  # FMU without energy|Map the FMU's cumulative charge to `energy`, or rank by `risk, time`.
C507|no chain parameters|With `fmu.chain.delivery: parameters` the FMU must take the chain as settable parameters (`chain.count` as an Integer, `chain.max_wheel_rate[i]`, `chain.delta_position[i]`, `chain.delta_heading[i]`, or the names mapped in `fmu.parameters`).|fmu: {path: kinematic.fmu}  # no chain.* variables|Map its chain parameters, or use `chain: {delivery: inputs, inputs: {…}}` or `delivery: none`.
C508|set-points and delivery disagree|`delivery: inputs` needs `fmu.chain.inputs` (FMU input: set-point); `chain.inputs` given with another delivery would never be fed.|chain: {delivery: inputs}|Add `inputs: {v_set: body.speed}`, or drop `inputs`.
C509|unknown set-point|A value of `fmu.chain.inputs` must be one of the set-points the tool computes from the chain (`wheel.rate[FL]`…, `body.speed`, `body.yaw_rate`, `command`).|inputs: {v_set: body.velocity}|Use `body.speed`.
C510|FMU cannot receive the terrain|The campaign gives terrain or rocks, but the FMU has no `terrain.file` input: its runs do not see them (a warning); collisions are still checked geometrically against the campaign's rocks.|environment: {rocks: [...]}  # kinematic FMU|Accept the warning, or give the FMU a terrain input.
C511|signal mapped twice|One signal is mapped from two FMU variables; only one can be read.|signals: {x: px, x: p_x}|Keep one.
C512|collisions need the pose|The rulebook reads collisions, which place the rover's bodies by its pose; the map lacks some of `x, y, z, roll, pitch, yaw`.|signals: {x: px, y: py}|Map the FMU's pose outputs, or use a rulebook without collision indices.
C513|run time is the stop time|The map provides neither `command` nor `done`, so a run's time is the simulation's stop time (a warning).|signals: {x: px, y: py}|Map an output that reports the chain complete to `done` (with `fmu.done_at`).
C514|the report draws no runs|The map provides no `x` or no `y`: the report's result maps show no runs and there are no box plots (a warning).|signals: {yaw: psi}|Map the position outputs to `x` and `y`.
F401|signal of an unreadable type|When the FMU is opened, a mapped signal turns out to be a String, Binary or Clock variable.|signals: {command: label}|Map a Real, Integer, Boolean or Enumeration output.
F402|unknown set-point|An FMU set-point name is not one the tool computes.|inputs: {v: body.velocity}|Use one of `wheel.rate[FL]`…, `body.speed`, `body.yaw_rate`, `command`.
F403|unit of the wrong dimension|The FMU declares a unit for a mapped variable that is not of the signal's or set-point's dimension.|signals: {yaw: x_mm}|Map a variable of that dimension.
C600|campaign file too large|A campaign file larger than 256 KiB is refused before it is read: campaigns are a few kB, so a larger file is a wrong path or a generated file that would take long to parse.|idefix-verify results/rock-detour/results.h5|Name the campaign's `.yaml` file; split a generated campaign into several files.
C601|terrain file too large|A terrain file (header and heights) or DEM (`.npy`, `.csv`) larger than the FMU can read (16 million nodes) is refused before it is read.|dem: survey-full-resolution.npy  # 2 GB|Resample the DEM to a coarser cell, or cut it to the area the chains cross.
C700|adaptive setting with a fixed run count|`max_runs`, `min_runs` and `batch_runs` say how an adaptive campaign (`runs: auto`) grows; with a fixed `runs: N` they would be ignored.|runs: 200\nmax_runs: 400|Write `runs: auto` (with `max_runs: 400`), or remove the key.
C701|minimum above the cap|An adaptive campaign's `min_runs` (runs before the first look) exceeds its `max_runs` (the cap).|runs: auto\nmin_runs: 500\nmax_runs: 400|Lower `min_runs` or raise `max_runs`.
C702|--max-runs or --min-runs without an adaptive campaign|The options set an adaptive campaign's cap and minimum; the campaign has a fixed run count.|idefix-verify c.yaml --max-runs 400|Add `--runs auto`, or write `runs: auto` in the campaign.
C710|nothing uncertain to search|`idefix-verify worst` searches the campaign's uncertain parameters for the worlds of highest run risk; the campaign's `uncertainty.parameters` gives none that varies (only `fixed` values, or none at all).|uncertainty:\n  parameters:\n    soil.n: {distribution: fixed, value: 1.0}|Give the parameters the search may vary a distribution: `initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}`.
C711|run budget too small for a worst-case search|A search needs a first generation (a Latin hypercube of the campaign's distributions, twice a generation's size), at least one more generation, and the failure boundary's share (up to 10 runs per ray); `--runs` per path is below that for the campaign's number of uncertain parameters.|idefix-verify worst campaign.yaml --runs 40|Give the number of runs the message names, or more: `--runs 150`.
C712|critical level above what the rulebook can reach|A run's I_max is the largest weighted index, at most the largest index weight; `--critical` asks for a level no run of this rulebook can reach, so no boundary could ever be found.|idefix-verify worst campaign.yaml --critical 1   # every weight is 0.8|Give `--critical` at most the largest weight (`--critical 0.8`), or look at the weights.
C713|a search into a campaign's folder|`idefix-verify worst --out DIR` names a folder that holds a campaign's `results.h5`; the search would set it aside (as `results.previous.h5`) to write its own, so the campaign's results would no longer be where its summary and report say.|idefix-verify worst campaigns/rock-detour.yaml --out results/rock-detour|Leave out `--out` (the search writes into the campaign's output folder + `/worst`) or give a folder of its own.
E800|reduction over runs out of place|A reduction `over runs` gives one value for the whole path (across its Monte Carlo runs). Only index values, maps and chances see the runs; verdicts already read path statistics (`mean(I_pos)`, `chance(X)`), and command rules and prescreens see a single run.|verdict v: require mean over runs (x) <= 1 m|Use it in an index: `value = final over time (hypot(mean over runs (x - ref.x), mean over runs (y - ref.y)))`.
E801|reduction over runs inside another|A reduction over runs cannot contain another one: the inner one already has no run axis left to reduce.|value = mean over runs (max over runs (x))|Reduce over runs once, outermost: `max over runs (x)`.
E802|collision signal reduced over runs|Collision signals are per run; the chance of a collision across runs is what a `chance` declares.|value = fraction over runs (collision.count > 0)|Declare `chance hit = any over time (collision.count > 0)` and read `chance(hit)` in a verdict.
E803|reducer that cannot reduce over runs|Run order means nothing, so `final`, `initial`, `integral` and `time_above` (which need time order) cannot reduce over runs.|value = final over runs (x)|Use `mean`, `sum`, `rms`, `max`, `min`, `percentile`, `any`, `all`, `count` or `fraction` over runs.
E804|percentile over runs of a series|`percentile over runs` needs one value per run; the operand still has a time (or wheel) axis.|value = percentile 95 over runs (x)|Reduce time first: `percentile 95 over runs (final over time (x))`.
E900|rulebook too large|A rulebook larger than 128 KiB is refused before it is parsed (the operations rulebook is 7 kB); a larger file is a wrong path or a generated file.|idefix-verify check results.h5|Name the `.rules` file; keep generated rules to what the campaign needs.
E901|rulebook line too long|A rulebook line longer than 20 000 characters is refused before it is parsed; `fmt` writes lines of at most 100 characters.|index I_s "slip" { value = a + a + a + … (one 50 MB line)|Break the expression into named constants or indices, then run `idefix-verify fmt`.
E902|not a rulebook|The file named as a rulebook does not start like one (a `rulebook` header, a comment or a declaration); only its first word is shown, never its content.|idefix-verify check /etc/passwd|Name the `.rules` file.
W613|number is a denormal or 0 in SI|(`--strict`) A literal is so small that in SI, once its unit's scale is applied, it is a denormal (below about 2.2e-308, precision lost) or 0 (`5e-324 mm`). A literal a double cannot hold at all (`1e-400`) is an error (E003).|const tiny = 1e-320|Write `0` if zero is meant, or a realistic value.
W614|nominal nearly at 0 or at the limit|(`--strict`) An index's `nominal` lies within 10 % of its limit from 0 or from the limit. The index climbs from 0 to 0.5 up to the nominal and from 0.5 to 1 between the nominal and the limit, so half of its range is crossed within a tenth of the value's: the index is nearly a step and no longer grades the runs.|index I_s {\n  value   = max over time (max over wheels (abs(wheel.slip)))\n  nominal = 68 %\n  limit   = 70 %\n  weight  = 1\n}|Put the nominal where the value is expected: `nominal = 20 %`; or leave `nominal` out for `value / limit`.
"""


def _parse(table: str) -> dict[str, Explanation]:
    entries = {}
    for line in table.strip().splitlines():
        code, title, explanation, example, fix = (part.replace("\\n", "\n")
                                                  for part in line.split("|"))
        entries[code] = Explanation(code, title, explanation, example, fix)
    return entries


CODES: dict[str, Explanation] = _parse(_TABLE)


def explain(code: str) -> Explanation | None:
    """The entry of ``code`` (case-insensitive), or None."""
    return CODES.get(code.strip().upper())
