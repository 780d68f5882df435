//! Adds an rpath to MuJoCo's folder so the module finds libmujoco.so when imported from a
//! locally built wheel; `maturin build --auditwheel repair` (what `make python` runs) also copies
//! the library into the wheel and points the module at that copy.
fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    match std::env::var("MUJOCO_DYNAMIC_LINK_DIR") {
        Ok(dir) => println!("cargo::rustc-link-arg=-Wl,-rpath,{dir}"),
        Err(_) => panic!(
            "MUJOCO_DYNAMIC_LINK_DIR is not set: build from inside the repository \
             (its .cargo/config.toml sets it) after `make mujoco`."
        ),
    }
}
