"""Every key of the configuration, section by section, with its default and its meaning:
declared once.

The parsers accept exactly these keys (schema.py takes its ``*_KEYS`` tuples from here),
and docs/config.md is generated from them (``python -m rollmpc_codegen.config.doc``), so
the reference cannot drift from what the reader accepts.  A default reads ``{NAME}``
where a value declared in schema.py (or the stage that owns it) gives it: config/doc.py
fills those in.  A key of a section backed by a dataclass (solver, units, target) that
gives no default text shows its field's default.
"""
from __future__ import annotations

from dataclasses import dataclass

REQUIRED = "required"


@dataclass(frozen=True)
class Key:
    name: str
    default: str | None  # as docs/config.md shows it; None: the dataclass field's default
    meaning: str
    group: str = ""  # a subset the parser treats apart (the scheduler's two-mode shorthand)


@dataclass(frozen=True)
class Section:
    path: str  # "modes[].weights"; "" is the top level
    about: str  # one sentence for the generated reference
    keys: tuple[Key, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(k.name for k in self.keys)


SECTIONS = (
    Section("", "The top level: the controller as a whole.", (
        Key("prefix", "`{DEFAULT_PREFIX}`", "C prefix of every generated file, function, type "
            "and macro: a lower-case identifier of at most 31 characters, not a system "
            "header's name such as `math` or `time` (its `P.h` would shadow it)"),
        Key("precision", "`{DEFAULT_PRECISION}`", "`double` or `float` (`--precision` "
            "overrides it); float is the Cortex-M4F's build"),
        Key("sample_time", REQUIRED, "Ts in seconds"),
        Key("horizon", REQUIRED, "N, the prediction steps; U has N·nu entries (p·nu with "
            "move blocking)"),
        Key("control_horizon", "none", "Nc, 1 <= Nc <= N: u_k = u_{{Nc-1}} for k >= Nc (the "
            "blocks [1, ..., 1, N - Nc + 1]) in every mode; `modes[].control_horizon` "
            "overrides it (features.md, \"Control horizon and move blocking\")"),
        Key("move_blocking", "none", "block lengths [b_1, ..., b_p], each >= 1, summing to "
            "N: each block of stages holds one input vector, so the QP has p·nu variables; "
            "not together with `control_horizon` at the same level"),
        Key("outputs", REQUIRED, "names of the measured outputs, shared by every mode"),
        Key("actuators", REQUIRED, "names of the physical actuators: the order of `u` in "
            "`P_step`, an inactive one getting 0"),
        Key("modes", REQUIRED, "one entry per mode (`modes[]` below); one mode needs no "
            "scheduler"),
        Key("scheduler", "none", "which mode is active (`scheduler` below); required with "
            "two modes or more"),
        Key("runtime_bounds", "`false`", "`true`: every mode's input and output bounds live "
            "in `P_ctrl` and change between samples through `P_set_bounds` (the same rows; "
            "bounds the config leaves infinite stay so); `false`: baked in "
            "(features.md, \"Run-time bounds\")"),
        Key("solver", "the defaults below", "the QP solver (`solver` below)"),
        Key("simulation", "the paper's scenario", "what `rollmpc simulate`, `bench`, "
            "`report` and `testvectors` fly (`simulation` below)"),
        Key("units", "none", "labels only (`units` below)"),
        Key("target", "the defaults below", "the part `rollmpc report` judges on and "
            "`rollmpc generate` sizes against (`target` below)"),
        Key("aircraft", "none", "the JSBSim aircraft and envelope `rollmpc identify` "
            "measured the modes on; `rollmpc fly` flies it (`aircraft` below)"),
    )),
    Section("modes[]", "One operating point: its plant, weights, bounds and observer.", (
        Key("name", REQUIRED, "identifier of the mode"),
        Key("actuators", "every actuator", "the physical actuators this mode drives, in its "
            "input order (the columns of B, of its transfer-function matrix); may be left "
            "out when it drives all of them in the top-level order"),
        Key("plant", REQUIRED, "the mode's model (`modes[].plant` below)"),
        Key("weights", REQUIRED, "the cost (`modes[].weights` below)"),
        Key("bounds", REQUIRED, "the constraints (`modes[].bounds` below)"),
        Key("observer", "pole placement at the default poles", "the state estimator "
            "(`modes[].observer` below)"),
        Key("control_horizon", "the top level's", "this mode's Nc (overrides the top "
            "level; `control_horizon: N` switches blocking off)"),
        Key("move_blocking", "the top level's", "this mode's block lengths"),
        Key("constraints", "none", "general constraints beyond the bounds: signals the "
            "outputs do not measure, mixed state-input rows, a terminal set "
            "(`modes[].constraints` below)"),
    )),
    Section("modes[].plant", "Exactly one of `transfer_function` and `state_space`.", (
        Key("transfer_function", "–", "`{{num, den}}`: a continuous SISO transfer function, or "
            "a matrix: `num` one row per output of one element per mode actuator, `den` the "
            "same shape or one common list (features.md, \"Transfer-function "
            "matrices\")"),
        Key("state_space", "–", "`{{A, B, C, D, discrete}}`"),
        Key("integrator", "`false`", "append 1/s to every output (eq. 1 of the paper: roll "
            "angle = G(s)/s); a biproper plant (D != 0) needs it"),
    )),
    Section("modes[].plant.transfer_function", "Coefficients in descending powers of s.", (
        Key("num", REQUIRED, "numerator: a list, or a matrix of lists (rows: outputs)"),
        Key("den", REQUIRED, "denominator: a list, or a matrix of lists, or one common list"),
    )),
    Section("modes[].plant.state_space", "x+ = A x + B u (or dx/dt), y = C x + D u.", (
        Key("A", REQUIRED, "nx x nx"),
        Key("B", REQUIRED, "nx x nu"),
        Key("C", REQUIRED, "ny x nx"),
        Key("D", "0", "ny x nu; nonzero only with `integrator: true`"),
        Key("discrete", "`false`", "`true`: A, B are already sampled at `sample_time`"),
    )),
    Section("modes[].weights", "J = Σ y'Qy + u'Ru (+ Δu'R_delta Δu), P on the last stage.", (
        Key("Q", REQUIRED, "stage output weight on y_1..y_{{N-1}}"),
        Key("R", REQUIRED, "input weight; positive definite, or semidefinite (e.g. 0) with a "
            "positive definite `R_delta`"),
        Key("P", "`Q`", "terminal output weight: it **replaces** Q on y_N (Ω = diag(Q, ..., Q, "
            "P)); the default weights every stage alike"),
        Key("R_delta", "none", "Δu weight (nu x nu, positive semidefinite): (u_k − u_{{k−1}})' "
            "R_delta (u_k − u_{{k−1}}) over the horizon, u_{{−1}} = the previous command; adds "
            "nu states to the mode's model, the C is unchanged (features.md, \"Δu "
            "weighting\")"),
    )),
    Section("modes[].bounds", "Hard unless `soft` says otherwise; `.inf` is allowed where "
            "a side is open.", (
        Key("u_min", REQUIRED, "lower input bounds; must contain 0 (the inactive command)"),
        Key("u_max", REQUIRED, "upper input bounds"),
        Key("y_min", "unbounded", "lower output bounds on y_1..y_N"),
        Key("y_max", "unbounded", "upper output bounds on y_1..y_N"),
        Key("du_min", "no limit", "input-rate limit du_min <= u_k − u_{{k−1}}, k = 0..N−1, "
            "u_{{−1}} = the previous command; must contain 0; adds the previous input as nu "
            "states; not with `runtime_bounds` (features.md, \"Δu constraints\")"),
        Key("du_max", "no limit", "input-rate limit u_k − u_{{k−1}} <= du_max"),
        Key("soft", "every bound hard", "soft output bounds (`modes[].bounds.soft` below)"),
    )),
    Section("modes[].bounds.soft", "An output bound made soft: one slack s >= 0 per output, "
            "side and stage.", (
        Key("y_min", "hard", "the penalty of the lower output bounds "
            "(`modes[].bounds.soft.<side>` below)"),
        Key("y_max", "hard", "the penalty of the upper output bounds"),
    )),
    Section("modes[].bounds.soft.<side>", "J += l1 s + l2 s² per slack; the QP stays "
            "feasible, and `P_last_info()->slack_max` reports the largest slack.", (
        Key("l1", REQUIRED, "linear penalty, >= 0 (scalar or one per output); above the "
            "multipliers the hard bound needs, the soft plan is the hard one (exact penalty)"),
        Key("l2", REQUIRED, "quadratic penalty, > 0 to soften that output; l1 = l2 = 0 keeps "
            "it hard (features.md, \"Soft output bounds\")"),
    )),
    Section("modes[].constraints", "General linear constraints, each a row on a signal: a "
            "linear combination of the plant's states x and the mode's inputs u at one time "
            "(features.md, \"General constraints\"). x is the state_space plant's as written, "
            "then its integrators; a transfer-function plant's states are the generator's, "
            "so there only inputs can be named.", (
        Key("signals", "none", "`{{name: {{C, D, min, max, stages, soft}}}}`: z = C x + D u held "
            "in [min, max], measured or not (`modes[].constraints.signals.<name>`)"),
        Key("mixed", "none", "`{{name: {{E, F, g, stages, soft}}}}`: the rows E x + F u <= g, one "
            "signal `name[i]` each"),
        Key("terminal", "none", "`lqr_invariant`, `equality` or `{{kind: polytope, H, h}}`: a "
            "constraint on x_N in deviation from the steady state of r_N "
            "(`modes[].constraints.terminal`)"),
    )),
    Section("modes[].constraints.signals.<name>", "One scalar constrained signal z = C x + D u.", (
        Key("C", "0", "one coefficient per plant state (with integrators, their columns may be "
            "left out)"),
        Key("D", "0", "one coefficient per mode input; with it the rows are at times 0..N-1, "
            "without it at 1..N"),
        Key("min", "none", "lower bound; at least one of min and max"),
        Key("max", "none", "upper bound"),
        Key("stages", "all", "`[first, last]` or one time k: the times the bound holds at"),
        Key("soft", "hard", "`{{l1, l2}}`: both finite sides soft, J += l1 s + l2 s² per slack"),
    )),
    Section("modes[].constraints.mixed.<name>", "Rows E x + F u <= g (upper bounds only: "
            "write -E, -F, -g for a lower one).", (
        Key("E", "0", "rows x plant states"),
        Key("F", "0", "rows x mode inputs; at least one of E and F"),
        Key("g", REQUIRED, "one right-hand side per row"),
        Key("stages", "all", "as for a signal"),
        Key("soft", "hard", "as for a signal"),
    )),
    Section("modes[].constraints.terminal", "A constraint on the predicted x_N, in deviation "
            "from the steady state x_s that holds r_N (features.md, \"Terminal constraints\"); "
            "`terminal: lqr_invariant` is short for `{{kind: lqr_invariant}}`.", (
        Key("kind", REQUIRED, "`lqr_invariant` (the maximal admissible set of the terminal "
            "LQR, computed), `polytope` (H (x_N - x_s) <= h) or `equality` (x_N = x_s)"),
        Key("H", "–", "polytope only: rows x plant states"),
        Key("h", "–", "polytope only: one right-hand side per row, >= 0"),
        Key("soft", "hard", "`{{l1, l2}}`: every terminal row soft alike"),
    )),
    Section("modes[].observer", "The mode's estimator; every mode's observer runs every "
            "sample.", (
        Key("kind", "`poles`", "`poles` (pole placement) or `kalman` (steady-state Kalman "
            "predictor)"),
        Key("poles", "{POLE_LOW} … {POLE_HIGH}, evenly", "discrete observer poles (`[re, im]` "
            "pairs for complex ones), one per state (nx + nd; the previous-input states of "
            "Δu are deadbeat, not configured); poles that placement cannot reach within 1e-4 "
            "are a config error naming this key"),
        Key("Qn", "required with `kalman`", "input-noise covariance (nu x nu)"),
        Key("Rn", "required with `kalman`", "measurement-noise covariance (ny x ny, positive "
            "definite)"),
        Key("Qd", "required with `kalman` and a disturbance", "the disturbance's random-walk "
            "covariance (nd x nd)"),
        Key("disturbance", "`none`", "offset-free tracking: `input` (one constant disturbance "
            "per mode input) or `output` (one per output) disturbance model"),
        Key("innovation_limit", "{INNOVATION_LIMIT_SPANS:g} spans of the output's expected "
            "range", "per output (a scalar for all), > 0: every observer clips each "
            "innovation y − C x̂ to ±this, and `P_step` reports `MEASUREMENT_CLIPPED`; `.inf` "
            "= off. The expected range is the hull of 0, the output's finite bounds and, on "
            "an open side, the scenario's reference levels; an unbounded output with a zero "
            "reference has no default. Baked in (features.md, \"Measurement "
            "plausibility\")"),
    )),
    Section("scheduler", "Band scheduling with hysteresis, eq. (3) of the paper generalised "
            "to k modes (features.md, \"k modes\").", (
        Key("signal", REQUIRED, "name of the scheduling signal (`P_step`'s `sched[0]`)"),
        Key("bands", "required (or the shorthand)", "k >= 2 bands in increasing order of the "
            "signal: `{{mode, below}}`, ..., the last `{{mode}}` (`scheduler.bands[]` below); a "
            "mode may serve several bands"),
        Key("epsilon", "`{DEFAULT_EPSILON}`", "hysteresis margin of every threshold"),
        Key("initial", "the band of 0 (shorthand: `inside`)", "mode after `P_init`"),
        Key("lower", "–", "two-mode shorthand of eq. (3): the lower threshold", "shorthand"),
        Key("upper", "–", "the upper threshold", "shorthand"),
        Key("inside", "–", "the mode between the thresholds", "shorthand"),
        Key("outside", "–", "the mode outside them", "shorthand"),
    )),
    Section("scheduler.bands[]", "One band: the mode that serves it and its upper "
            "threshold.", (
        Key("mode", REQUIRED, "the mode of this band"),
        Key("below", "required but on the last band", "the threshold between this band and "
            "the next"),
        Key("epsilon", "`scheduler.epsilon`", "the hysteresis margin of that threshold"),
    )),
    Section("solver", "The QP solver (solver.md); `work_budget` is the one setting a "
            "design usually sizes.", (
        Key("method", None, "`hildreth`, `hildreth_plus` or `hildreth_plus_prime` (the "
            "paper's variants; the fallback after the exact solves)"),
        Key("omega", None, "SOR factor of Hildreth+ and +' (plain Hildreth uses 1)"),
        Key("sigma", None, "reduced-set margin of Hildreth+' (rows with K < σ)"),
        Key("delta", None, "the sweeps stop when ‖λᵐ − λᵐ⁻¹‖² < δ"),
        Key("max_iterations", None, "sweep cap (status `MAX_ITER`)"),
        Key("warm_start", None, "reuse the previous multipliers"),
        Key("polish", None, "exact active-set solves (`false`: the paper's sweeps alone)"),
        Key("polish_first", None, "polish from the shifted warm start, then from the violated "
            "rows, before any sweep"),
        Key("polish_every", None, "sweeps between polish attempts"),
        Key("polish_max", None, "active-set corrections per polish attempt"),
        Key("feasibility_tol", "`{FEAS_DOUBLE}` double, `{FEAS_FLOAT}` float", "relative: a "
            "row holds when its violation is <= tol · max(1, \\|γ\\|)"),
        Key("active_set", None, "dual active-set (Goldfarb-Idnani) solve when the polishes "
            "fail, before any sweep; it proves infeasibility (needs `polish: true`)"),
        Key("active_set_max", None, "its cap on add/drop steps, then the sweeps"),
        Key("dependence_tol", "`{DEP_DOUBLE}` double, `{DEP_FLOAT}` float", "a row whose "
            "pivot is below tol · H_pp is dependent on the working set"),
        Key("work_budget", None, "work units (about one multiply-add each) a QP solve may "
            "spend; past it the status is `TIME_LIMIT`. `auto`: `budget_share` of the sample "
            "time at `target.cpu_mhz`, at the target core's cycles per unit ({CYCLES_PER_WORK_UNIT:g} "
            "on the default Cortex-M4F; target.md \"Parts\"), less {STEP_FIXED_UNITS} units for the "
            "step outside the solver (no budget with `polish: false`) "
            "(solver.md, \"Sizing\")"),
        Key("budget_share", None, "the fraction of the sample time `work_budget: auto` gives "
            "the solver"),
    )),
    Section("simulation", "What the commands that fly a scenario fly; the generated C "
            "never sees it.", (
        Key("schedule_source", "`output_rate`", "what `rollmpc simulate` feeds as `sched`: "
            "`output_rate` (the pre-integrator output, the roll rate) or `output`"),
        Key("reference", "the paper's scenario", "`simulation.reference` below"),
    )),
    Section("simulation.reference", "A piecewise-constant reference.", (
        Key("levels", "{PAPER_LEVELS}", "the levels, in order; a level is a scalar (every "
            "output) or one value per output"),
        Key("segment", "{PAPER_SEGMENT_S:g} s", "how long each level is held, s"),
    )),
    Section("units", "Labels only: the units `rollmpc simulate` prints and plots; without "
            "them no unit is shown.", (
        Key("outputs", "none", "a string for every output, or one per output"),
        Key("actuators", "none", "a string for every actuator, or one per actuator"),
        Key("schedule", "none", "the scheduling signal's unit"),
    )),
    Section("target", "The microcontroller; the generated C never sees it.", (
        Key("cpu_mhz", None, "its clock: a step's budget is cpu_mhz · 10⁶ · `sample_time` "
            "cycles; `work_budget: auto` follows it, and `generate` refuses a design whose "
            "estimated step without active bounds exceeds it"),
        Key("flash_kib", "none (generate: {DEFAULT_FLASH_LIMIT_KIB} KiB)", "flash the image must "
            "fit: `report` judges against it, `generate` refuses a float build predicted "
            "beyond it (unless `--force-size`)"),
        Key("ram_kib", "none (generate: {DEFAULT_RAM_LIMIT_KIB} KiB)", "static RAM the image, and "
            "the controller instance alone, must fit"),
        Key("part", "none", "a declared part (`stm32f427`, `stm32f765`, `stm32h743`, "
            "`stm32l562`, ...: parts.py, target.md \"Parts\"): its core, clock, flash and RAM, "
            "each of which a key above may override; `--part` of generate and report "
            "replaces this section with it"),
        Key("core", None, "without a part: the core (`cortex-m4f`, `cortex-m7`, "
            "`cortex-m33`), its flags, FPU width, cycle model and cycles per work unit"),
    )),
    Section("aircraft", "What `rollmpc identify` wrote about the aircraft (flight.md, \"The "
            "config\"): `rollmpc fly` takes its defaults from here and warns where a flight "
            "leaves the envelope; the generated C never sees it.", (
        Key("name", REQUIRED, "the JSBSim aircraft (a model of the jsbsim wheel)"),
        Key("altitude_ft", REQUIRED, "the trim altitude of every mode, ft: `fly` holds it"),
        Key("airspeeds_kts", REQUIRED, "the calibrated trim airspeed of each mode, in the "
            "modes' order: `fly` starts at the initial mode's and warns outside their range"),
        Key("aileron_travel_deg", REQUIRED, "`[min, max]`: the left aileron's deflection "
            "at full command, measured at steady state through the aircraft's FCS"),
        Key("aileron_rate_dps", "none (no rate limit)", "the aileron actuator's largest "
            "rate, deg/s, measured on the same full-command steps"),
        Key("stall_alpha_deg", "none", "the angle of attack of maximum lift, deg: a "
            "flight counts the samples above it as stalled"),
        Key("latency_samples", "`0`", "samples of sensor latency the modes model "
            "(`identify --latency`): `fly` compares its `--delay` against it and the "
            "delay margin"),
        Key("settings", "none", "`{{property: value}}`: JSBSim properties set after the "
            "engines start, before the trim, and held through every flight (gear, flaps, "
            "mixture: `identify --gear/--flaps/--set`)"),
    )),
)


def section(path: str) -> Section:
    """The section at ``path`` ("" for the top level)."""
    return next(s for s in SECTIONS if s.path == path)


def section_keys(path: str, group: str | None = None) -> tuple[str, ...]:
    """The keys the section at ``path`` accepts (of ``group`` only, when given)."""
    return tuple(k.name for k in section(path).keys if group is None or k.group == group)
