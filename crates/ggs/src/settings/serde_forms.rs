//! How settings that are not plain numbers read and write: a memory size as bytes or `"2G"`,
//! the refinement as a method name or `"none"`, a robust kernel as `"huber:0.01"`.

use crate::refine::{Method, RobustKernel};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serializer};

/// `null`, a number of bytes, or a size such as `"2G"` or `"512M"`.
pub(super) fn optional_size<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u64>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Size {
        Bytes(u64),
        Text(String),
    }
    match Option::<Size>::deserialize(d)? {
        None => Ok(None),
        Some(Size::Bytes(b)) => Ok(Some(b)),
        Some(Size::Text(t)) => crate::memory::parse_size(&t).map(Some).ok_or_else(|| {
            D::Error::custom(format!("cannot read '{t}' as a size (try 2G or 512M)"))
        }),
    }
}

/// The refinement as its name: `"gicp"`, `"p2plane"`, `"p2p"` or `"none"`.
pub(super) fn write_refinement<S: Serializer>(m: &Option<Method>, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(m.map_or("none", |m| m.name()))
}

/// The refinement from its name ([`write_refinement`]).
pub(super) fn read_refinement<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Method>, D::Error> {
    let name = String::deserialize(d)?;
    if name == "none" {
        return Ok(None);
    }
    Method::from_name(&name).map(Some).ok_or_else(|| {
        D::Error::custom(format!(
            "unknown refinement '{name}' (gicp, p2plane, p2p or none)"
        ))
    })
}

/// A robust kernel as text: `"none"`, `"huber:K"`, `"cauchy:K"` or `"geman-mcclure:K"`.
pub(super) fn write_kernel<S: Serializer>(k: &RobustKernel, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(k)
}

/// A robust kernel from its text ([`write_kernel`]).
pub(super) fn read_kernel<'de, D: Deserializer<'de>>(d: D) -> Result<RobustKernel, D::Error> {
    String::deserialize(d)?
        .parse()
        .map_err(|e: crate::GgsError| D::Error::custom(e.to_string()))
}
