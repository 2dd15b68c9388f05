# Two commands on a fresh machine (see README):
#   make demo   - a complete tuning run over ROS 2 topics on the embedded default task
#   make test   - lint + the whole test suite (what CI runs)
# Both create ./.venv on first use and install everything they need into it.

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.localpbo-installed

.PHONY: demo test install lint clean

install: $(STAMP)

$(STAMP): pyproject.toml setup.py
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else "Python 3.11 is required (set PYTHON=...)")'
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	# The local CPU build of torch first, so no dependency pulls the CUDA build.
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet -e '.[ros,test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/localpbo run

lint: $(STAMP)
	$(BIN)/ruff check .

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup

clean:
	rm -rf $(VENV) ros_ws/build ros_ws/install ros_ws/log
