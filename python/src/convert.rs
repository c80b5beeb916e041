//! What crosses the boundary: errors, settings dicts, numpy arrays of points and indices.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use tissue::Vec3;

use crate::TissueError;

/// A library error as a Python exception with the library's message.
pub fn err(e: impl std::fmt::Display) -> PyErr {
    TissueError::new_err(e.to_string())
}

/// A settings dict (scene key names) as the TOML table the library parses.
pub fn table(dict: Option<&Bound<'_, PyDict>>, what: &str) -> PyResult<toml::Table> {
    let mut out = toml::Table::new();
    if let Some(d) = dict {
        for (k, v) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| err(format!("{what}: keys must be strings, not {k}")))?;
            let value = value(&v, &format!("{what}.{key}"))?;
            out.insert(key, value);
        }
    }
    Ok(out)
}

fn value(v: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    // bool before int: Python's bool is an int.
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        let i: i64 = v
            .extract()
            .map_err(|_| err(format!("{key}: the integer {v} does not fit in 64 bits")))?;
        return Ok(toml::Value::Integer(i));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(table(Some(d), key)?));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let items = v
            .try_iter()?
            .map(|item| value(&item?, key))
            .collect::<PyResult<Vec<_>>>()?;
        return Ok(toml::Value::Array(items));
    }
    // numpy scalars and arrays: through their Python value.
    if let Ok(x) = v.extract::<f64>() {
        return Ok(toml::Value::Float(x));
    }
    if let Ok(list) = v.call_method0("tolist") {
        return value(&list, key);
    }
    Err(err(format!(
        "{key}: cannot use a value of type {} (numbers, strings, booleans, lists and dicts only)",
        v.get_type().name()?
    )))
}

/// Any array-like (numpy array, list of lists) as a 2-D float64 numpy array.
fn float_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<PyReadonlyArray2<'py, f64>> {
    let np = obj.py().import("numpy")?;
    let a = np
        .call_method1("asarray", (obj, "float64"))
        .map_err(|e| err(format!("{what}: not an array of numbers ({e})")))?;
    let a = if a.getattr("size")?.extract::<usize>()? == 0 {
        a.call_method1("reshape", (0, 3))?
    } else {
        a
    };
    a.extract().map_err(|_| {
        err(format!(
            "{what}: expected an (n, 3) array, got shape {}",
            shape(&a)
        ))
    })
}

/// Any array-like of integers as an int64 numpy array; floats are refused, not truncated.
fn int_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = obj.py().import("numpy")?;
    let a = np
        .call_method1("asarray", (obj,))
        .map_err(|e| err(format!("{what}: not an array of indices ({e})")))?;
    if a.getattr("size")?.extract::<usize>()? == 0 {
        return np.call_method1("zeros", (0, "int64"));
    }
    let kind: String = a.getattr("dtype")?.getattr("kind")?.extract()?;
    if kind != "i" && kind != "u" {
        return Err(err(format!(
            "{what}: indices must be integers, got an array of dtype {}",
            a.getattr("dtype")?
        )));
    }
    a.call_method1("astype", ("int64",))
}

fn shape(a: &Bound<'_, PyAny>) -> String {
    a.getattr("shape")
        .map_or_else(|_| "?".into(), |s| s.to_string())
}

/// An (n, 3) array-like as points, refusing other shapes and non-finite values.
pub fn points(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vec3>> {
    let a = float_array(obj, what)?;
    let a = a.as_array();
    if a.ncols() != 3 {
        return Err(err(format!(
            "{what}: expected an (n, 3) array, got shape {:?}",
            a.shape()
        )));
    }
    let mut out = Vec::with_capacity(a.nrows());
    for (i, row) in a.rows().into_iter().enumerate() {
        let p = Vec3::new(row[0], row[1], row[2]);
        if !p.is_finite() {
            return Err(err(format!("{what}: row {i} is not finite ({p})")));
        }
        out.push(p);
    }
    Ok(out)
}

/// One point from any 3-sequence.
pub fn point(v: [f64; 3], what: &str) -> PyResult<Vec3> {
    let p = Vec3::from_array(v);
    if !p.is_finite() {
        return Err(err(format!("{what}: {p} is not finite")));
    }
    Ok(p)
}

/// An (n, K) array-like of integers as index rows, each a non-negative 32-bit index.
pub fn index_rows<const K: usize>(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[u32; K]>> {
    let a = int_array(obj, what)?;
    let a = if a.getattr("ndim")?.extract::<usize>()? == 1
        && a.getattr("size")?.extract::<usize>()? == 0
    {
        a.call_method1("reshape", (0, K))?
    } else {
        a
    };
    let a: PyReadonlyArray2<'_, i64> = a.extract().map_err(|_| {
        err(format!(
            "{what}: expected an (n, {K}) array, got shape {}",
            shape(&a)
        ))
    })?;
    let a = a.as_array();
    if a.ncols() != K {
        return Err(err(format!(
            "{what}: expected an (n, {K}) array, got shape {:?}",
            a.shape()
        )));
    }
    a.rows()
        .into_iter()
        .enumerate()
        .map(|(i, row)| {
            let mut out = [0u32; K];
            for (o, &x) in out.iter_mut().zip(row) {
                *o = u32::try_from(x)
                    .map_err(|_| err(format!("{what}: row {i} has the index {x}")))?;
            }
            Ok(out)
        })
        .collect()
}

/// A 1-D array-like of integers as vertex indices.
pub fn indices(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<u32>> {
    let a: PyReadonlyArray1<'_, i64> = int_array(obj, what)?
        .extract()
        .map_err(|_| err(format!("{what}: expected a 1-D array of vertex indices")))?;
    a.as_array()
        .iter()
        .enumerate()
        .map(|(i, &x)| u32::try_from(x).map_err(|_| err(format!("{what}: entry {i} is {x}"))))
        .collect()
}

/// Points as an (n, 3) float array.
pub fn points_array<'py>(py: Python<'py>, p: &[Vec3]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat: Vec<f64> = p.iter().flat_map(|v| v.to_array()).collect();
    rows_array(py, flat, 3)
}

/// Index rows as an (n, K) uint32 array.
pub fn rows_u32<'py, const K: usize>(
    py: Python<'py>,
    r: &[[u32; K]],
) -> PyResult<Bound<'py, PyArray2<u32>>> {
    let flat: Vec<u32> = r.iter().flatten().copied().collect();
    rows_array(py, flat, K)
}

fn rows_array<T: numpy::Element>(
    py: Python<'_>,
    flat: Vec<T>,
    k: usize,
) -> PyResult<Bound<'_, PyArray2<T>>> {
    let n = flat.len() / k;
    let a = Array2::from_shape_vec((n, k), flat).map_err(err)?;
    Ok(a.into_pyarray(py))
}

/// A JSON value as the Python object `json.loads` would give.
pub fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    let json = py.import("json")?;
    json.call_method1("loads", (v.to_string(),))
}

/// An (n, 3) float64 numpy array of points or forces.
pub type Points<'py> = Bound<'py, PyArray2<f64>>;
/// An (n, K) uint32 numpy array of index rows.
pub type Rows<'py> = Bound<'py, PyArray2<u32>>;
