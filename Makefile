# rollmpc: every target creates/uses its own virtual environment in .venv.
#   make demo    generate the UAV controller and simulate it (the main job)
#   make test    all tests (pytest, including the host C tests)
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
ROLLMPC := $(VENV)/bin/rollmpc
EXAMPLES := uav_roll
CC ?= gcc
CSTRICT := -std=c99 -O2 -ffp-contract=off -Wall -Wextra -Wpedantic -Wconversion -Wshadow \
           -Wdouble-promotion -Werror

.PHONY: all venv demo generate test ctest check-long clean

all: test

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --upgrade pip
	$(VENV)/bin/pip install --quiet -e '.[all]'
	touch $@

venv: $(VENV)/.installed

## demo: generate the paper's controller (double and float) and run the 60 s scenario
demo: venv generate
	@mkdir -p build/demo
	$(ROLLMPC) simulate examples/uav_roll.yaml --csv build/demo/uav_roll.csv \
	    --json build/demo/uav_roll.json --plot build/demo/uav_roll.png --baseline lqr
	@echo "demo: see build/demo/uav_roll.png, build/demo/uav_roll.json"

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

## check-long: long runs (sanitizer soak, large fuzz budgets)
check-long: venv
	$(PY) -m pytest -q -m slow --runslow

clean:
	rm -rf build
