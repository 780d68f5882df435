//! Adds an rpath to MuJoCo's folder so tests and binaries run without LD_LIBRARY_PATH.
fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    match std::env::var("MUJOCO_DYNAMIC_LINK_DIR") {
        Ok(dir) => {
            let lib = std::path::Path::new(&dir).join("libmujoco.so");
            if !lib.exists() {
                panic!(
                    "MuJoCo is not installed: {} is missing. Run `make mujoco` \
                     (or scripts/install-mujoco.sh) in the repository root first.",
                    lib.display()
                );
            }
            println!("cargo::rustc-link-arg=-Wl,-rpath,{dir}");
        }
        Err(_) => panic!(
            "MUJOCO_DYNAMIC_LINK_DIR is not set: build from inside the repository \
             (its .cargo/config.toml sets it) after `make mujoco`."
        ),
    }
}
