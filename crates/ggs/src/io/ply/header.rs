//! The PLY header: encoding, elements, their properties and scalar types.

use crate::error::{GgsError, Result};
use std::path::Path;

/// The longest header accepted (comments included).
pub(super) const MAX_HEADER_BYTES: usize = 16 << 20;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    pub(super) fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// Decode one value from the first `self.size()` bytes of `b`.
    #[inline(always)]
    pub(super) fn decode(self, b: &[u8], little: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("caller passes enough bytes");
                if little {
                    <$t>::from_le_bytes(a)
                } else {
                    <$t>::from_be_bytes(a)
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2) as f64,
            Scalar::U16 => get!(u16, 2) as f64,
            Scalar::I32 => get!(i32, 4) as f64,
            Scalar::U32 => get!(u32, 4) as f64,
            Scalar::F32 => get!(f32, 4) as f64,
            Scalar::F64 => get!(f64, 8),
        }
    }
}

#[derive(Debug, Clone)]
pub(super) enum Property {
    Scalar(Scalar, String),
    List(Scalar, Scalar, String),
}

#[derive(Debug, Clone)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: usize,
    pub(super) props: Vec<Property>,
}

impl Element {
    /// Whether every property is a scalar (no list): rows of a fixed number of values.
    pub(super) fn scalars_only(&self) -> bool {
        self.props.iter().all(|p| matches!(p, Property::Scalar(..)))
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Encoding {
    Ascii,
    BinaryLe,
    BinaryBe,
}

pub(super) struct Header {
    pub(super) encoding: Encoding,
    pub(super) elements: Vec<Element>,
    /// Byte offset of the first data byte.
    pub(super) data_start: usize,
    /// Number of header lines (so ascii data line numbers can be reported).
    pub(super) lines: usize,
}

/// The encoding named by a `format` line.
pub(super) fn parse_format(path: &Path, line_no: usize, word: Option<&str>) -> Result<Encoding> {
    match word {
        Some("ascii") => Ok(Encoding::Ascii),
        Some("binary_little_endian") => Ok(Encoding::BinaryLe),
        Some("binary_big_endian") => Ok(Encoding::BinaryBe),
        other => Err(GgsError::at_line(
            path,
            line_no,
            format!("unknown format {other:?} (expected ascii, binary_little_endian or binary_big_endian)"),
        )),
    }
}

/// The rest of a `property` line: `TYPE NAME` or `list COUNT_TYPE ITEM_TYPE NAME`.
pub(super) fn parse_property<'a>(
    path: &Path,
    line_no: usize,
    tok: &mut impl Iterator<Item = &'a str>,
) -> Result<Property> {
    let t = tok.next().unwrap_or("");
    if t == "list" {
        let ct = tok.next().and_then(Scalar::parse);
        let it = tok.next().and_then(Scalar::parse);
        return match (ct, it, tok.next()) {
            (Some(c), Some(i), Some(n)) => Ok(Property::List(c, i, n.to_string())),
            _ => Err(GgsError::at_line(
                path,
                line_no,
                "expected 'property list COUNT_TYPE ITEM_TYPE NAME'",
            )),
        };
    }
    let ty = Scalar::parse(t)
        .ok_or_else(|| GgsError::at_line(path, line_no, format!("unknown property type '{t}'")))?;
    let name = tok
        .next()
        .ok_or_else(|| GgsError::at_line(path, line_no, "property without a name"))?;
    Ok(Property::Scalar(ty, name.to_string()))
}

pub(super) fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(GgsError::at_line(
                path,
                line_no + 1,
                "the header ends before 'end_header'",
            ));
        };
        let raw = &bytes[pos..pos + nl];
        pos += nl + 1;
        line_no += 1;
        let line = String::from_utf8_lossy(raw);
        let line = line.trim();
        let mut tok = line.split_whitespace();
        let key = tok.next().unwrap_or("");
        if line_no == 1 {
            if key != "ply" {
                return Err(GgsError::at_line(path, 1, "expected 'ply' magic line"));
            }
            continue;
        }
        match key {
            "format" => encoding = Some(parse_format(path, line_no, tok.next())?),
            "element" => {
                let name = tok.next().unwrap_or("").to_string();
                let count = tok
                    .next()
                    .and_then(|c| c.parse::<usize>().ok())
                    .ok_or_else(|| {
                        GgsError::at_line(path, line_no, "expected 'element NAME COUNT'")
                    })?;
                elements.push(Element {
                    name,
                    count,
                    props: Vec::new(),
                });
            }
            "property" => {
                let el = elements.last_mut().ok_or_else(|| {
                    GgsError::at_line(path, line_no, "'property' before any 'element'")
                })?;
                el.props.push(parse_property(path, line_no, &mut tok)?);
            }
            "end_header" => break,
            // comment, obj_info and anything unknown: skipped.
            _ => {}
        }
    }
    let encoding =
        encoding.ok_or_else(|| GgsError::in_file(path, "the header has no 'format' line"))?;
    Ok(Header {
        encoding,
        elements,
        data_start: pos,
        lines: line_no,
    })
}
