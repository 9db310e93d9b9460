# pickplan: one-command set-up. `make demo` and `make test` each install everything they
# need (Debian packages, a local virtual environment, the native extension) and then run.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
NATIVE_BUILD := build/native
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
OUT ?= out

SYSTEM_PACKAGES := g++ make pkg-config python3-venv python3-dev \
  libeigen3-dev libfcl-dev libccd-dev liburdfdom-dev liburdfdom-headers-dev \
  libnlopt-cxx-dev coinor-libipopt-dev libgtest-dev libnanoflann-dev liblapack-dev libblas-dev ccache \
  chromium
PYTHON_BUILD_PACKAGES := "scikit-build-core>=0.10" "pybind11>=2.12" "cmake>=3.18" ninja
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test system-deps venv install test-cpp test-python bench clean

demo: install
	$(PY) -m pickplan demo --out $(OUT)/demo

test: install test-cpp test-python

# Idempotent: installs only what is missing.
system-deps:
	@missing=""; for p in $(SYSTEM_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; \
	else echo "Debian packages: all present"; fi

$(VENV)/.stamp: pyproject.toml
	[ -x $(PY) ] || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q $(PYTHON_BUILD_PACKAGES) numpy scipy pybullet trimesh rtree scikit-learn matplotlib pytest ompl ray meshcat u-msgpack-python
	touch $@

venv: $(VENV)/.stamp

install: system-deps venv
	$(PIP) install -q --no-build-isolation --no-deps .

test-cpp: system-deps venv
	$(VENV)/bin/cmake -S . -B $(NATIVE_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV))/bin/ninja \
	  -DPICKPLAN_BUILD_TESTS=ON -DPICKPLAN_BUILD_PYTHON=OFF -DPICKPLAN_BUILD_BENCH=ON
	$(VENV)/bin/cmake --build $(NATIVE_BUILD) -j $(JOBS)
	$(VENV)/bin/ctest --test-dir $(NATIVE_BUILD) --output-on-failure -j $(JOBS)

test-python: install
	$(PY) -m pytest tests/python -q

bench: install
	$(VENV)/bin/pickplan-bench

clean:
	rm -rf build $(OUT)
