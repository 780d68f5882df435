# Two commands for a fresh clone (see README):
#   make demo   -- the main job: a simulated A1 walking under EEMP, metrics and figures in out/demo
#   make test   -- every test (what .ci/run runs)
# Both install MuJoCo 3.17.0 into .mujoco/ first (from the PyPI wheel; nothing else is needed).
.PHONY: mujoco demo stand test lint bench

MUJOCO := .mujoco/lib/libmujoco.so

$(MUJOCO):
	./scripts/install-mujoco.sh

mujoco: $(MUJOCO)

demo: $(MUJOCO)
	cargo run --release -p eemp-cli -- walk --gait trot --speed 0.3 --duration 20 --out out/demo --video out/demo/walk.gif

stand: $(MUJOCO)
	cargo run --release -p eemp-cli -- stand --duration 20 --out out/stand

test: $(MUJOCO)
	cargo fmt --all -- --check
	cargo clippy --workspace --all-targets -- -D warnings
	cargo test --workspace

bench: $(MUJOCO)
	cargo run --release -p eemp-cli -- bench mpc
