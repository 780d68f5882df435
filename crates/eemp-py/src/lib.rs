//! `eemp._eemp`: the Rust side of the `eemp` Python package. The package's Python modules
//! (`python/eemp/`) build the gymnasium environments on [`envs::PyVecEnv`]; everything that
//! steps, plans or measures runs here, in the project's crates, with the GIL released.

mod control;
mod envs;

use pyo3::prelude::*;

#[pymodule]
fn _eemp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<envs::PyVecEnv>()?;
    m.add_class::<control::PyEempController>()?;
    m.add_class::<control::PyA1Sim>()?;
    m.add_function(wrap_pyfunction!(envs::env_seed_of, m)?)?;
    m.add_function(wrap_pyfunction!(envs::rust_rollout, m)?)?;
    m.add_function(wrap_pyfunction!(envs::rust_stepping_rate, m)?)?;
    m.add_function(wrap_pyfunction!(control::walk_json, m)?)?;
    m.add("LEG_ORDER", ["FR", "FL", "RR", "RL"])?;
    Ok(())
}
