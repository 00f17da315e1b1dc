//! `meshmatch._native`: the Python package's extension module (PyO3). numpy in, numpy out; one
//! function per system, each calling the same in-memory entry point as the CLI subcommand
//! (`meshmatch::cli::<command>`), so parameters, defaults, checks and messages are the CLI's.
//!
//! Long calls run on a thread of their own while the calling thread, the GIL released between
//! polls, passes progress to the Python callback, watches the cancel token and checks for Ctrl-C
//! ([`job::run`]).

mod job;
mod mesh;
mod systems;

use pyo3::prelude::*;

pyo3::create_exception!(
    meshmatch,
    MeshMatchError,
    pyo3::exceptions::PyException,
    "A meshmatch call was refused or failed; the message is the CLI's one line."
);
pyo3::create_exception!(
    meshmatch,
    Cancelled,
    MeshMatchError,
    "A meshmatch call was stopped through its CancelToken."
);

/// The Python exception for an engine error.
pub(crate) fn to_py(e: meshmatch::Error) -> PyErr {
    match e {
        meshmatch::Error::Cancelled => Cancelled::new_err("cancelled"),
        e => MeshMatchError::new_err(e.to_string()),
    }
}

/// An engine result as a Python result.
pub(crate) trait OrPy<T> {
    fn or_py(self) -> PyResult<T>;
}

impl<T> OrPy<T> for meshmatch::Result<T> {
    fn or_py(self) -> PyResult<T> {
        self.map_err(to_py)
    }
}

/// A refusal of a Python argument, as a [`MeshMatchError`].
pub(crate) fn refuse<T>(msg: impl Into<String>) -> PyResult<T> {
    Err(MeshMatchError::new_err(msg.into()))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("MeshMatchError", py.get_type::<MeshMatchError>())?;
    m.add("Cancelled", py.get_type::<Cancelled>())?;
    m.add_class::<mesh::Mesh>()?;
    m.add_class::<job::CancelToken>()?;
    m.add_function(wrap_pyfunction!(mesh::load, m)?)?;
    systems::register(m)?;
    Ok(())
}
