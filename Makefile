# fuzzyservo: every target sets itself up (creates .venv when missing and installs the project).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
# pyfuzzylite pins numpy<2, so the benchmark runs it in an environment of its own.
FLVENV := .venv-fuzzylite
PIP_QUIET := $(if $(CI),-q,)

.PHONY: all reproduce test test-fast lint bench clean clean-cache oracles crosscheck precompile browser matiec

all: test

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install $(PIP_QUIET) --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install $(PIP_QUIET) -e '.[test,bench,distributed,app]'
	touch $(STAMP)

$(FLVENV)/.installed-stamp:
	$(PYTHON) -m venv $(FLVENV)
	$(FLVENV)/bin/python -m pip install $(PIP_QUIET) 'pyfuzzylite>=8' 'numpy<2'
	touch $@

# Independent readers the tests compare with: fuzzylite's CLI (Debian package, about 1 MB);
# and the C compiler the export tests build the generated code and FMUs with (gcc, with its
# address and undefined-behaviour sanitizers, and the C library's headers). Installed when
# missing (root, or sudo); the tests that need them fail, never skip, without them.
APT_INSTALL = DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -q --no-install-recommends
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
ORACLE_PKGS := fuzzylite gcc libc6-dev
oracles:
	@{ command -v fuzzylite && command -v gcc && [ -f /usr/include/stdio.h ]; } >/dev/null 2>&1 \
	  || $(APT_INSTALL) $(ORACLE_PKGS) \
	  || { $(SUDO) apt-get update -q && $(APT_INSTALL) $(ORACLE_PKGS); }

# The browser the page's tests drive (fuzzyservo app, tests/app): Debian's Chromium and its
# ChromeDriver (browsers cannot be downloaded here; about 250 MB installed, ~15 s). Installed
# when missing; the tests fail, never skip, without them.
BROWSER_PKGS := chromium chromium-driver
browser:
	@{ [ -x /usr/bin/chromium ] && [ -x /usr/bin/chromedriver ]; } >/dev/null 2>&1 \
	  || $(APT_INSTALL) $(BROWSER_PKGS) \
	  || { $(SUDO) apt-get update -q && $(APT_INSTALL) $(BROWSER_PKGS); }

# MatIEC (iec2c), the IEC 61131-3 compiler of Beremiz and OpenPLC: the outside checker of the
# Structured Text that 'fuzzyservo export st' writes (tests/export/test_st.py). Built once, into
# the ignored folder .oracles/matiec, from $(MATIEC_SRC) (a folder holding matiec-src.tar.gz
# and build-matiec.sh, or the tarball itself) with the LREAL-literal patch beside it (about 50 s
# on two cores; installs autoconf, automake, libtool, flex and bison with apt when missing).
# GPL v3: used only to check, never shipped or linked. The ST tests fail, never skip, without it.
MATIEC_SRC ?= ../shared/oracles/matiec
MATIEC := .oracles/matiec
matiec: $(MATIEC)/bin/iec2c
$(MATIEC)/bin/iec2c:
	@src="$(MATIEC_SRC)"; \
	if [ -d "$$src" ]; then dir="$$src"; tarball="$$src/matiec-src.tar.gz"; \
	else dir="$$(dirname "$$src")"; tarball="$$src"; fi; \
	[ -f "$$tarball" ] && [ -f "$$dir/build-matiec.sh" ] || { \
	  echo "WARNING: MatIEC's source is not in $$src: the Structured Text tests will fail. Set MATIEC_SRC to the folder holding matiec-src.tar.gz and build-matiec.sh (default ../shared/oracles/matiec)" >&2; exit 0; }; \
	rm -rf $(MATIEC).tmp; \
	PATCHES="$$(cd "$$dir" && ls matiec-lreal-literal.patch 2>/dev/null)" \
	  bash "$$dir/build-matiec.sh" "$$tarball" "$$PWD/$(MATIEC).tmp" && \
	rm -rf $(MATIEC) && mv $(MATIEC).tmp $(MATIEC)

# Optional: Octave's fuzzy-logic-toolkit reads and evaluates our exported .fis files (about
# 270 MB installed, so not part of `make test`).
crosscheck: $(STAMP)
	@command -v octave >/dev/null 2>&1 && [ -n "$$(ls -d /usr/share/octave/packages/fuzzy-logic-toolkit* 2>/dev/null)" ] \
	  || $(APT_INSTALL) octave octave-fuzzy-logic-toolkit \
	  || { $(SUDO) apt-get update -q && $(APT_INSTALL) octave octave-fuzzy-logic-toolkit; }
	$(BIN)/python benchmarks/crosscheck_octave.py

reproduce: precompile
	$(BIN)/fuzzyservo reproduce --out results/paper

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy src

# The compiled kernels take about 40 s to compile on a fresh clone (fuzzyservo precompile, two
# processes); once, first, into the package's cache (keyed by the sources: an edit compiles
# afresh what it touches), every test worker and every process a test starts loads them in a
# fraction of a second instead of compiling them again (docs/architecture.md, "Compiled
# kernels").
precompile: $(STAMP)
	$(BIN)/fuzzyservo precompile

# the 15 slowest tests are listed at the end (the suite is to stay under 10 minutes in CI)
test: lint oracles browser matiec precompile
	$(BIN)/python -m pytest -n 2 -q --durations=15

# the same without the tests marked slow (brute-force accuracy, the README's study and tuning
# runs): a quick check while editing; CI and `make test` run everything
test-fast: lint oracles browser matiec precompile
	$(BIN)/python -m pytest -n 2 -q -m "not slow"

bench: browser precompile $(FLVENV)/.installed-stamp
	$(BIN)/python benchmarks/run_all.py --fuzzylite-python $(FLVENV)/bin/python

# The compiled kernels' cache cannot go stale (its folder is named by a digest of the
# sources), so nothing needs clearing after an edit; this removes the folders of every version
# (~/.cache/fuzzyservo, or $$FUZZYSERVO_CACHE_DIR) and numba's caches of the tests and benchmarks.
clean-cache:
	rm -rf "$${FUZZYSERVO_CACHE_DIR:-$${XDG_CACHE_HOME:-$$HOME/.cache}/fuzzyservo}"
	find src tests benchmarks -name '*.nbi' -delete -o -name '*.nbc' -delete

clean: clean-cache
	rm -rf $(VENV) $(FLVENV) build *.egg-info src/*.egg-info .pytest_cache .mypy_cache .ruff_cache
