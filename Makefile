# Two commands do all the set-up on a fresh machine: `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench clean

$(STAMP): pyproject.toml
	test -d $(VENV) || $(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# torch first and pinned: 2.13.0 is the CPU build on these machines; an unpinned
	# torch pulls a CUDA build of several GB.
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

# One ReverseAlarm episode, told in words; runs/demo.{png,rrd,wav,json}. Fast models unless
# DEMO_ARGS says otherwise, e.g. make demo DEMO_ARGS="--profile paper --seed 3".
DEMO_ARGS ?=
demo: $(STAMP)
	$(BIN)/acoustic-sim demo --out runs $(DEMO_ARGS)

# Two workers (CI and a laptop have at least two cores): the suite's episodes split between them.
test: $(STAMP)
	$(BIN)/pytest -q -n 2

bench: $(STAMP)
	$(BIN)/acoustic-sim bench render --out bench/render.json

clean:
	rm -rf $(VENV) runs bench .pytest_cache
