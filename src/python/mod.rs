//! The `khepera_gym._core` Python module: the `Batch` and `Policy` classes and the functions
//! the Python package builds on. The only place pyo3 appears; each file has one job:
//! `errors` (exceptions and the panic guard), `convert` (Python values into the core's),
//! `batch` (the Batch class), `state` (its saved states and pickling), `views` (the core's data
//! as Python dicts of arrays, for the Batch's inspection methods), `policy` (the Policy class),
//! `functions` (module functions).
//!
//! Threading and copies: every call checks its inputs while holding the GIL, copies them into
//! Rust-owned buffers, releases the GIL (`py.detach`) for the simulation, then copies results
//! into freshly allocated NumPy arrays. No Python object crosses into the released section.

mod batch;
mod convert;
mod errors;
mod functions;
mod policy;
mod state;
mod views;

use pyo3::prelude::*;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<batch::Batch>()?;
    m.add_class::<policy::PyPolicy>()?;
    m.add_function(wrap_pyfunction!(state::_batch_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(functions::tasks, m)?)?;
    m.add_function(wrap_pyfunction!(functions::task_versions, m)?)?;
    m.add_function(wrap_pyfunction!(functions::versions, m)?)?;
    m.add_function(wrap_pyfunction!(functions::task_scoring, m)?)?;
    m.add_function(wrap_pyfunction!(functions::task_agents, m)?)?;
    m.add_function(wrap_pyfunction!(functions::motor_presets, m)?)?;
    m.add_function(wrap_pyfunction!(functions::controllers, m)?)?;
    m.add_function(wrap_pyfunction!(functions::controller_params, m)?)?;
    m.add_function(wrap_pyfunction!(functions::formation_offsets, m)?)?;
    m.add_function(wrap_pyfunction!(functions::braitenberg_weights, m)?)?;
    m.add_function(wrap_pyfunction!(functions::obs_layout, m)?)?;
    m.add_function(wrap_pyfunction!(functions::default_config, m)?)?;
    m.add_function(wrap_pyfunction!(functions::builtin_configs, m)?)?;
    m.add_function(wrap_pyfunction!(functions::speed_to_units, m)?)?;
    m.add_function(wrap_pyfunction!(functions::units_to_speed, m)?)?;
    m.add_function(wrap_pyfunction!(functions::simd_paths, m)?)?;
    m.add_function(wrap_pyfunction!(functions::simd_path, m)?)?;
    m.add_function(wrap_pyfunction!(functions::force_simd, m)?)?;
    m.add_function(wrap_pyfunction!(functions::_panic_for_test, m)?)?;
    m.add("LATEST_VERSION", crate::scenario::LATEST_VERSION)?;
    m.add("MAX_WHEEL_SPEED", crate::robot::MAX_WHEEL_SPEED)?;
    m.add("MIN_WHEEL_SPEED", crate::robot::MIN_WHEEL_SPEED)?;
    m.add("AXLE_LENGTH", crate::robot::AXLE_LENGTH)?;
    m.add("BODY_RADIUS", crate::robot::BODY_RADIUS)?;
    m.add("WHEEL_RADIUS", crate::robot::WHEEL_RADIUS)?;
    Ok(())
}
