# Two commands for a fresh clone (see README):
#   make demo   -- the main job: a simulated A1 walking under EEMP, metrics and figures in out/demo
#   make test   -- every test (what .ci/run runs)
# Both install MuJoCo 3.17.0 into .mujoco/ first (from the PyPI wheel; nothing else is needed).
.PHONY: mujoco demo stand test lint bench python python-test python-dev-test viewer viewer-test dds-peer

MUJOCO := .mujoco/lib/libmujoco.so
# The Python tools (maturin, numpy, gymnasium, pytest) in .venv.
VENV := .venv/.installed

$(MUJOCO):
	./scripts/install-mujoco.sh

mujoco: $(MUJOCO)

# The demo's build leaves out what a walk under EEMP does not use (`--no-default-features`: no
# training or policies, so no candle; no robot link, so no DDS): half the compile time of the
# whole command on a fresh 2-core clone (docs/reproduce.md). `cargo build --release -p eemp-cli`
# builds everything.
DEMO_BUILD := --release -p eemp-cli --no-default-features

demo: $(MUJOCO)
	cargo run $(DEMO_BUILD) -- walk --gait trot --speed 0.3 --duration 20 --out out/demo --video out/demo/walk.gif

stand: $(MUJOCO)
	cargo run $(DEMO_BUILD) -- stand --duration 20 --out out/stand

# `make test` tests the Rerun recorder through Python's rerun-sdk (in .venv; EEMP_PYTHON picks
# it, EEMP_REQUIRE_RERUN makes its absence a failure). Rerun's Rust SDK (`eemp-viz/sdk`,
# `eemp-cli/rerun`) is left out: its ≈ 300 crates were 35 % of a fresh 2-core clone's test
# build (≈ 3.8 min), more than the 12 min budget leaves; `make viewer-test` tests it.
# Clippy lints inside the test build: clippy-driver compiles the workspace's own crates, as
# `cargo clippy` has it do (the same two variables), so the dependencies are compiled once
# instead of also being checked by a separate `cargo clippy` (≈ 5 min less on a fresh 2-core
# clone). `cargo test` builds every target here (lib, bins, tests; no examples or benches), the
# set `cargo clippy --all-targets` lints. `make lint` is the plain `cargo clippy`.
# A one-off build (CI's): no incremental state and 16 codegen units instead of 256 (a fresh
# 2-core clone's test build 10 min 55 s against 11 min 37 s, docs/reproduce.md).
CLIPPY_IN_BUILD := CARGO_INCREMENTAL=0 CARGO_PROFILE_DEV_CODEGEN_UNITS=16 CARGO_PROFILE_TEST_CODEGEN_UNITS=16 \
	RUSTC_WORKSPACE_WRAPPER="$$(rustc --print sysroot)/bin/clippy-driver" \
	CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"
# The Go2's DDS interop test talks to a peer on Eclipse Cyclone DDS's own Python binding
# (`cyclonedds` from PyPI, in .venv-dds, with Unitree's own IDL classes and CRC from the
# `unitree-sdk2` wheel); EEMP_REQUIRE_DDS_PEER=1 makes a missing peer a failure
# instead of a loud skip.
DDS_PEER := .venv-dds/.installed-cyclonedds-11.0.1-unitree-sdk2-1.0.1

$(DDS_PEER):
	./scripts/install-dds-peer.sh

dds-peer: $(DDS_PEER)

# The Python package is tested from the test build itself (`python-dev-test`), not from a wheel:
# a wheel's `maturin build -p eemp-py` resolves other features than the workspace's test build
# and recompiled ~100 dependencies (≈ 3.5 min on 2 cores). `make python` builds the wheel,
# `make python-test` tests it.
TEST_SCOPE := --workspace
PY_ENV := PYO3_PYTHON="$(CURDIR)/.venv/bin/python"
RERUN_PY := EEMP_PYTHON="$(CURDIR)/.venv/bin/python" EEMP_REQUIRE_RERUN=1

test: $(MUJOCO) $(DDS_PEER) $(VENV)
	cargo fmt --all -- --check
	EEMP_REQUIRE_DDS_PEER=1 $(RERUN_PY) $(CLIPPY_IN_BUILD) $(PY_ENV) cargo test $(TEST_SCOPE)
	$(MAKE) python-dev-test

# Also lints `make demo`'s build (no default features): not in `make test`, where its other
# feature set recompiles the dependencies whose features differ (1 min 51 s on 2 cores after a
# test build).
lint:
	cargo clippy --workspace --all-targets --features eemp-cli/rerun -- -D warnings
	cargo clippy -p eemp-cli --no-default-features -- -D warnings

# The Python package (crates/eemp-py): an optimised wheel (profile `python`: release without debug
# info) in target/wheels with libmujoco inside (auditwheel repair), installed into .venv with its
# test tools (≈ 2.5 min from scratch on 2 cores).
WHEEL_PROFILE ?= python

$(VENV): crates/eemp-py/requirements-dev.txt
	./scripts/install-python.sh

python: $(MUJOCO) $(VENV)
	rm -f target/wheels/eemp-*.whl
	@# maturin repairs the linked module in place: relink, so each repair starts from the original.
	touch crates/eemp-py/src/lib.rs
	PATH="$(CURDIR)/.venv/bin:$$PATH" PYO3_PYTHON="$(CURDIR)/.venv/bin/python" \
		maturin build --profile $(WHEEL_PROFILE) -m crates/eemp-py/Cargo.toml --out target/wheels --auditwheel repair
	.venv/bin/pip install --quiet --disable-pip-version-check --force-reinstall --no-deps target/wheels/eemp-*.whl

python-test: python
	.venv/bin/python -m pytest -q crates/eemp-py/tests

# The extension from one more build of the whole workspace with the test build's targets and
# features (so only pyo3, numpy and eemp-py itself are new), staged with the package's Python
# sources in target/python-dev (libmujoco found through the module's rpath), then pytest.
PYDEV := target/python-dev
python-dev-test: $(MUJOCO) $(VENV)
	$(CLIPPY_IN_BUILD) $(PY_ENV) cargo build $(TEST_SCOPE) --lib --bins --tests
	rm -rf $(PYDEV) && mkdir -p $(PYDEV)/eemp
	ln -s $(CURDIR)/crates/eemp-py/python/eemp/*.py $(PYDEV)/eemp/
	cp target/debug/lib_eemp.so $(PYDEV)/eemp/_eemp.so
	PYTHONPATH=$(CURDIR)/$(PYDEV) .venv/bin/python -m pytest -q crates/eemp-py/tests

# Every `eemp` records (--rerun FILE.rrd, --rerun-connect, --rerun-serve) through a Python with
# rerun-sdk 0.36.3, which also brings the viewer (`rerun`): `make python` puts one in .venv
# (EEMP_PYTHON=.venv/bin/python), or pip install rerun-sdk==0.36.3. `make viewer` builds
# `eemp` with Rerun's Rust SDK inside instead (no Python needed to record): ~300 more crates, a
# few minutes more on 2 cores.
viewer: $(MUJOCO)
	cargo build --release -p eemp-cli --features rerun

# The recorder's tests with the Rust SDK too (every recording read back with rerun-sdk's own
# reader, the CLI's --rerun options, a viewer that never answers), with clippy, as `make test`.
viewer-test: $(MUJOCO) $(VENV)
	$(RERUN_PY) $(CLIPPY_IN_BUILD) cargo test -p eemp-viz --features sdk
	$(RERUN_PY) $(CLIPPY_IN_BUILD) cargo test -p eemp-cli --features rerun --lib --bins --test rerun

bench: $(MUJOCO)
	cargo run --release -p eemp-cli -- bench mpc
