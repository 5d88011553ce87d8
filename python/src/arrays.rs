//! numpy arrays ⇄ ggs types, and ggs errors as Python exceptions.

use ggs::rotations::RotationSet;
use ggs::{GgsError, Point, Rigid};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError, PyValueError};
use pyo3::prelude::*;

/// `FileNotFoundError` / `PermissionError` / `OSError` with `errno`, `strerror` and `filename`
/// for I/O errors, `KeyboardInterrupt` for a cancelled search, `ValueError` for the rest.
pub fn to_py_err(e: GgsError) -> PyErr {
    match &e {
        GgsError::Io { path, source } => {
            let args = (
                source.raw_os_error().unwrap_or(0),
                e.to_string(),
                path.display().to_string(),
            );
            match source.kind() {
                std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(args),
                std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(args),
                _ => PyOSError::new_err(args),
            }
        }
        GgsError::Cancelled => pyo3::exceptions::PyKeyboardInterrupt::new_err("cancelled"),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A `ValueError` from a ggs error (parameters).
pub fn value_err(e: GgsError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// An (N, 3) float32 or float64 array as points (read in place, whatever its strides).
/// Anything else is a `ValueError` naming the argument (the Python layer converts lists,
/// array-likes and objects with `.points` before calling).
pub fn points_of(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<Point>> {
    fn rows<T: Copy + Into<f64> + numpy::Element>(
        name: &str,
        a: PyReadonlyArray2<'_, T>,
    ) -> PyResult<Vec<Point>> {
        let view = a.as_array();
        let mut out = Vec::with_capacity(view.nrows());
        for (i, r) in view.rows().into_iter().enumerate() {
            let p: Point = [r[0].into(), r[1].into(), r[2].into()];
            if !p.iter().all(|c| c.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "{name}: row {i} has a NaN or infinite coordinate {p:?}"
                )));
            }
            out.push(p);
        }
        Ok(out)
    }
    let describe = || -> String {
        let dtype = obj
            .getattr("dtype")
            .map(|d| d.to_string())
            .unwrap_or_else(|_| obj.get_type().to_string());
        let shape = obj
            .getattr("shape")
            .map(|s| s.to_string())
            .unwrap_or_else(|_| "(no shape)".into());
        format!("{name}: expected an (N, 3) array of floats, got dtype {dtype} with shape {shape}")
    };
    let check_shape = |shape: &[usize]| -> PyResult<()> {
        if shape.len() != 2 || shape[1] != 3 {
            return Err(PyValueError::new_err(describe()));
        }
        if shape[0] == 0 {
            return Err(PyValueError::new_err(format!(
                "{name}: the array has no point"
            )));
        }
        Ok(())
    };
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f64>>() {
        check_shape(a.shape())?;
        return rows(name, a);
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f32>>() {
        check_shape(a.shape())?;
        return rows(name, a);
    }
    Err(PyValueError::new_err(describe()))
}

/// A 4×4 float64 array as a rigid transform.
pub fn matrix_of(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Rigid> {
    let a = obj
        .extract::<PyReadonlyArray2<'_, f64>>()
        .map_err(|_| PyValueError::new_err(format!("{name}: expected a 4×4 float64 array")))?;
    if a.shape() != [4, 4] {
        return Err(PyValueError::new_err(format!(
            "{name}: expected a 4×4 array, got shape {:?}",
            a.shape()
        )));
    }
    let v: Vec<f64> = a.as_array().iter().copied().collect();
    Rigid::from_row_major(&v, 1e-4).map_err(|m| PyValueError::new_err(format!("{name}: {m}")))
}

/// An (N, 3, 3) float64 array as a rotation set (every row checked to be a rotation).
pub fn rotations_of(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<RotationSet> {
    let a = obj.extract::<PyReadonlyArray3<'_, f64>>().map_err(|_| {
        PyValueError::new_err(format!("{name}: expected an (N, 3, 3) float64 array"))
    })?;
    let sh = a.shape();
    if sh.len() != 3 || sh[1] != 3 || sh[2] != 3 || sh[0] == 0 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected an (N, 3, 3) array with N ≥ 1, got shape {sh:?}"
        )));
    }
    let data: Vec<f64> = a.as_array().iter().copied().collect();
    RotationSet::from_row_major("array", &data)
        .map_err(|m| PyValueError::new_err(format!("{name}: {m}")))
}

pub fn points_array<'py>(py: Python<'py>, pts: &[Point]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = pts.iter().flat_map(|p| p.iter().copied()).collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([pts.len(), 3])?
        .into_any())
}
