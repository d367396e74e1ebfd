# rollmpc: every target creates/uses its own virtual environment in .venv.
#   make demo    generate the UAV controller and simulate it (the main job)
#   make test    all tests (pytest, including the host C tests)
PYTHON ?= python3
# one BLAS thread: the QPs are small and the machines have 2 cores (threaded OpenBLAS runs
# the extended-precision reference solves ~10x slower under load)
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1
VENV ?= .venv
PY := $(VENV)/bin/python
ROLLMPC := $(VENV)/bin/rollmpc
EXAMPLES := uav_roll chain_of_masses three_drives quadruple_tank thermal_zones chain_runtime_bounds thermal_zones_rate \
            uav_roll_blocked chain_soft c172_roll fw_lateral quad_attitude
CC ?= gcc
CSTRICT := -std=c99 -O2 -ffp-contract=off -Wall -Wextra -Wpedantic -Wconversion -Wshadow \
           -Wdouble-promotion -Werror

.PHONY: all venv demo generate test ctest check-long clean firmware size report figures \
        reliability flight-matrix mutation docs measurements

all: test

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --upgrade pip
	$(VENV)/bin/pip install --quiet -e '.[all]'
	touch $@

venv: $(VENV)/.installed

## demo: generate the paper's controller (double and float) and run the 60 s scenario
##   (the paper's controller only: `make generate` regenerates every example)
DEMO := uav_roll
demo: venv
	$(ROLLMPC) generate examples/$(DEMO).yaml -o generated/$(DEMO) --precision double
	$(ROLLMPC) generate examples/$(DEMO).yaml -o generated/$(DEMO)_f32 --precision float
	@mkdir -p build/demo
	$(ROLLMPC) simulate examples/$(DEMO).yaml --csv build/demo/$(DEMO).csv \
	    --json build/demo/$(DEMO).json --plot build/demo/$(DEMO).png --baseline lqr
	@echo "demo: see build/demo/$(DEMO).png, build/demo/$(DEMO).json"

## generate: regenerate the committed generated/ trees from examples/
generate: venv
	@for ex in $(EXAMPLES); do \
	    $(ROLLMPC) generate examples/$$ex.yaml -o generated/$$ex --precision double || exit 1; \
	    $(ROLLMPC) generate examples/$$ex.yaml -o generated/$${ex}_f32 --precision float || exit 1; \
	done

## test: the whole suite (the same command .ci/run calls)
test: venv
	$(PY) -m pytest -q

## ctest: host C test programs from reference vectors, built and run without Python
ctest: venv
	@for ex in $(EXAMPLES); do for prec in double float; do \
	    out=build/ctest/$${ex}_$$prec; \
	    $(ROLLMPC) testvectors examples/$$ex.yaml --precision $$prec -o $$out || exit 1; \
	    $(CC) $(CSTRICT) -I$$out $$out/*.c -lm -o $$out/test_vectors || exit 1; \
	    echo "ctest $$ex $$prec:"; ./$$out/test_vectors || exit 1; \
	done; done

## firmware: cross-compile firmware_stub + generated/uav_roll_f32 for a Cortex-M4F
##   (build/firmware/rollctl_m4f.elf; needs arm-none-eabi-gcc, see firmware_stub/README.md)
firmware:
	$(MAKE) -f firmware_stub/firmware.mk firmware

## size: flash and static RAM of the firmware image
size:
	$(MAKE) --no-print-directory -f firmware_stub/firmware.mk size

## report: flash, RAM, stack and cycles on an emulated Cortex-M4F (build/report/)
report: venv
	@mkdir -p build/report
	$(ROLLMPC) report examples/uav_roll.yaml --precision float --json build/report/uav_roll_f32.json

## figures: the paper reproduction (docs/paper-reproduction.md): Fig. 2 in both precisions,
##   Table 2 (--paper: the paper's variants besides ours and the peers) on 2000 of the
##   scenario's 5968 QPs (BENCH_ARGS= for all of them: ~12 CPU-min)
##   and our default against DAQP on every QP -> docs/figures/*.png, build/figures/
BENCH_ARGS ?= --max-qps 2000
figures: venv
	@mkdir -p docs/figures build/figures
	$(ROLLMPC) simulate examples/uav_roll.yaml --baseline lqr --plot docs/figures/fig2_closed_loop.png \
	    --json build/figures/fig2_double.json --csv build/figures/fig2_double.csv
	$(ROLLMPC) simulate examples/uav_roll.yaml --precision float --baseline lqr \
	    --plot build/figures/fig2_closed_loop_f32.png --json build/figures/fig2_float.json
	$(ROLLMPC) bench examples/uav_roll.yaml $(BENCH_ARGS) --paper --variants default,daqp,osqp,osqp_tight \
	    --json build/figures/table2.json --plot docs/figures/fig3_solve_times.png > build/figures/table2.md
	@cat build/figures/table2.md
	$(ROLLMPC) bench examples/uav_roll.yaml --variants default,daqp --repeat 5 \
	    --json build/figures/default_vs_daqp.json > build/figures/default_vs_daqp.md
	@cat build/figures/default_vs_daqp.md

## check-long: long runs (sanitizer soak, large fuzz budgets), then the mutation run
check-long: venv
	$(PY) -m pytest -q -m slow --runslow
	$(MAKE) --no-print-directory mutation

## mutation: plant each bug of rollmpc_codegen/verify/mutants.py in a copy of the tree and
##   report which tests catch it (docs/reliability.md, "Mutation testing"; ~1 h on 2 cores)
mutation: venv
	$(PY) -m rollmpc_codegen.verify.mutation --json build/mutation/mutation.json

## flight-matrix: the table of docs/flight.md: examples/c172_roll.yaml and the PID baseline
##   on the JSBSim c172p in every turbulence level, 3 seeds each, each MPC flight replayed
##   on the emulated M4F, and the latency table (needs the flight and target extras; ~4 CPU-min)
flight-matrix: venv
	@mkdir -p build/flight
	$(PY) -m rollmpc_codegen.flight.matrix --json build/flight/matrix.json > build/flight/matrix.md
	@cat build/flight/matrix.md

## reliability: measure the figures of docs/reliability.md into build/reliability/*.json
reliability: venv
	$(PY) -m rollmpc_codegen.verify --out build/reliability

## docs: docs/config.md from the schema (rollmpc_codegen/config/keys.py; a test pins it)
docs: venv
	$(PY) -m rollmpc_codegen.config.doc > docs/config.md

## measurements: every example's report, simulate and bench rows -> docs/measurements.md
##   (each row with its command and commit; 8-40 min on 2 shared cores, with the load;
##   MEASURE_ARGS="--only X,Y" for some examples, --render to re-render the JSON)
MEASURE_ARGS ?=
measurements: venv
	nice -n 10 $(PY) -m rollmpc_codegen.verify.measurements $(MEASURE_ARGS)

clean:
	rm -rf build
