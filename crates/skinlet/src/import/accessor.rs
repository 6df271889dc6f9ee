//! Bounds-checked reading of glTF accessors (glTF 2.0 section 3.6), sparse ones included.
//! Every offset, stride and count is checked against the buffer before a byte is read, so
//! corrupt files give an error that names the accessor, never a panic.

use crate::{Error, Result};
use gltf::accessor::{DataType, Dimensions};
use std::cell::Cell;
use std::collections::HashMap;

/// Loaded bytes of every buffer of the document, by buffer index, the decoded bytes of the
/// compressed buffer views, by view index, the values of accessors decoded from compressed
/// primitives (Draco), by accessor index, and how many more numbers (accessor components)
/// this import may read.
pub(crate) struct Buffers {
    data: Vec<Vec<u8>>,
    decoded: HashMap<usize, Vec<u8>>,
    accessors: HashMap<usize, Vec<f64>>,
    budget: Cell<usize>,
}

impl Buffers {
    /// The budget is 16 Mi numbers plus 4 per buffer byte: far above what real files read
    /// (about one per byte), but it stops a small file from making skinlet copy the same
    /// data (or a huge all-zero sparse accessor) once per referencing primitive until memory
    /// runs out.
    pub(crate) fn new(
        data: Vec<Vec<u8>>,
        decoded: HashMap<usize, Vec<u8>>,
        accessors: HashMap<usize, Vec<f64>>,
    ) -> Self {
        let bytes = data.iter().chain(decoded.values()).map(Vec::len).fold(0usize, usize::saturating_add);
        let numbers = accessors.values().map(Vec::len).fold(bytes, usize::saturating_add);
        let budget = Cell::new((1usize << 24).saturating_add(numbers.saturating_mul(4)));
        Buffers { data, decoded, accessors, budget }
    }

    fn spend(&self, count: usize, n: usize, loc: &str) -> Result<()> {
        let left = self.budget.get();
        match count.checked_mul(n) {
            Some(numbers) if numbers <= left => {
                self.budget.set(left - numbers);
                Ok(())
            }
            _ => Err(Error::unsupported(
                loc,
                format!(
                    "count {count} × {n} components would pass the limit on numbers read from one file \
                     ({left} left of 16 Mi + 4 per buffer byte; is the same data referenced many times?)"
                ),
            )),
        }
    }
}

fn components(d: Dimensions) -> usize {
    d.multiplicity()
}

fn where_(acc: &gltf::Accessor, what: &str) -> String {
    format!("accessor {} ({what})", acc.index())
}

/// Reads `count` elements of `n` components of type `ty` from a byte range.
#[allow(clippy::too_many_arguments)]
fn read_raw(
    bytes: &[u8],
    offset: usize,
    stride: usize,
    count: usize,
    n: usize,
    ty: DataType,
    normalized: bool,
    out: &mut Vec<f64>,
) {
    let size = ty.size();
    for i in 0..count {
        let base = offset + i * stride;
        for c in 0..n {
            let p = base + c * size;
            let b = &bytes[p..p + size];
            let v = match ty {
                DataType::I8 => {
                    let x = b[0] as i8 as f64;
                    if normalized { (x / 127.0).max(-1.0) } else { x }
                }
                DataType::U8 => {
                    let x = b[0] as f64;
                    if normalized { x / 255.0 } else { x }
                }
                DataType::I16 => {
                    let x = i16::from_le_bytes([b[0], b[1]]) as f64;
                    if normalized { (x / 32767.0).max(-1.0) } else { x }
                }
                DataType::U16 => {
                    let x = u16::from_le_bytes([b[0], b[1]]) as f64;
                    if normalized { x / 65535.0 } else { x }
                }
                DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            };
            out.push(v);
        }
    }
}

/// Checks that `count` elements of `elem` bytes at `offset` with `stride` fit in a buffer
/// view, and returns the view's bytes.
fn view_bytes<'b>(
    view: &gltf::buffer::View,
    buffers: &'b Buffers,
    offset: usize,
    stride: usize,
    elem: usize,
    count: usize,
    loc: &str,
) -> Result<&'b [u8]> {
    let bytes = match buffers.decoded.get(&view.index()) {
        Some(d) => d.as_slice(),
        None => stored_view(view, buffers, loc)?,
    };
    if count > 0 {
        let need =
            (count - 1).checked_mul(stride).and_then(|x| x.checked_add(offset)).and_then(|x| x.checked_add(elem));
        if need.is_none_or(|n| n > bytes.len()) {
            return Err(Error::invalid(
                loc,
                format!(
                    "{count} elements of {elem} bytes at offset {offset} with stride {stride} do not fit in buffer view {} ({} bytes)",
                    view.index(),
                    bytes.len()
                ),
            ));
        }
    }
    Ok(bytes)
}

/// The bytes of a view stored as such in its buffer, checked to lie inside it.
fn stored_view<'b>(view: &gltf::buffer::View, buffers: &'b Buffers, loc: &str) -> Result<&'b [u8]> {
    let buffer = buffers
        .data
        .get(view.buffer().index())
        .ok_or_else(|| Error::invalid(loc, format!("buffer {} is missing", view.buffer().index())))?;
    let end = view.offset().checked_add(view.length());
    if end.is_none_or(|e| e > buffer.len()) {
        return Err(Error::invalid(
            loc,
            format!(
                "buffer view {} (offset {}, length {}) runs past the end of buffer {} ({} bytes)",
                view.index(),
                view.offset(),
                view.length(),
                view.buffer().index(),
                buffer.len()
            ),
        ));
    }
    Ok(&buffer[view.offset()..view.offset() + view.length()])
}

/// Reads an accessor as `count × components` numbers (normalized integers mapped to
/// [0, 1] or [-1, 1] as the spec says), applying sparse substitution.
fn read_f64(acc: &gltf::Accessor, buffers: &Buffers, loc: &str) -> Result<Vec<f64>> {
    let n = components(acc.dimensions());
    if matches!(acc.dimensions(), Dimensions::Mat2 | Dimensions::Mat3) && acc.data_type().size() < 4 {
        return Err(Error::unsupported(loc, "padded 8/16-bit matrix accessors"));
    }
    let ty = acc.data_type();
    let elem = n * ty.size();
    let count = acc.count();
    if let Some(values) = buffers.accessors.get(&acc.index()) {
        // Decoded from a compressed primitive, already `count × n` numbers.
        buffers.spend(count, n, loc)?;
        return Ok(values.clone());
    }
    let mut out = Vec::new();
    match acc.view() {
        Some(view) => {
            let stride = view.stride().unwrap_or(elem);
            if stride < elem {
                return Err(Error::invalid(
                    loc,
                    format!("byteStride {stride} is smaller than the element size {elem}"),
                ));
            }
            let bytes = view_bytes(&view, buffers, acc.offset(), stride, elem, count, loc)?;
            // Only now is `count` known to be bounded (by the view's length).
            buffers.spend(count, n, loc)?;
            out.reserve_exact(count * n);
            read_raw(bytes, acc.offset(), stride, count, n, ty, acc.normalized(), &mut out);
        }
        None => {
            // No buffer view: zeros, as glTF defines it (sparse values, if any, come next);
            // only the budget bounds the count.
            buffers.spend(count, n, loc)?;
            out.resize(count * n, 0.0);
        }
    }
    if let Some(sparse) = acc.sparse() {
        let k = sparse.count();
        let idx = sparse.indices();
        let isize = idx.index_type().size();
        let ib = view_bytes(&idx.view(), buffers, idx.offset(), isize, isize, k, &format!("{loc}, sparse indices"))?;
        let itype = match isize {
            1 => DataType::U8,
            2 => DataType::U16,
            _ => DataType::U32,
        };
        let mut indices = Vec::with_capacity(k);
        read_raw(ib, idx.offset(), isize, k, 1, itype, false, &mut indices);
        let vals = sparse.values();
        let vb = view_bytes(&vals.view(), buffers, vals.offset(), elem, elem, k, &format!("{loc}, sparse values"))?;
        let mut values = Vec::with_capacity(k * n);
        read_raw(vb, vals.offset(), elem, k, n, ty, acc.normalized(), &mut values);
        for (s, &i) in indices.iter().enumerate() {
            let i = i as usize;
            if i >= count {
                return Err(Error::invalid(
                    loc,
                    format!("sparse index {i} (entry {s}) is not below the count {count}"),
                ));
            }
            out[i * n..(i + 1) * n].copy_from_slice(&values[s * n..(s + 1) * n]);
        }
    }
    Ok(out)
}

fn expect(acc: &gltf::Accessor, dims: &[Dimensions], loc: &str) -> Result<()> {
    if !dims.contains(&acc.dimensions()) {
        return Err(Error::invalid(loc, format!("expected type {:?}, found {:?}", dims, acc.dimensions())));
    }
    Ok(())
}

/// Float data (any component type) as `f32`, checked finite.
pub(crate) fn read_floats(
    acc: &gltf::Accessor,
    dims: &[Dimensions],
    buffers: &Buffers,
    what: &str,
) -> Result<Vec<f32>> {
    let loc = where_(acc, what);
    expect(acc, dims, &loc)?;
    let raw = read_f64(acc, buffers, &loc)?;
    let n = components(acc.dimensions());
    if let Some(i) = raw.iter().position(|x| !x.is_finite()) {
        return Err(Error::invalid(loc, format!("element {} holds a NaN or infinite value", i / n)));
    }
    Ok(raw.into_iter().map(|x| x as f32).collect())
}

/// Unsigned integer data (indices, joint numbers): u8, u16 or u32 components, not normalized.
pub(crate) fn read_uints(acc: &gltf::Accessor, dims: &[Dimensions], buffers: &Buffers, what: &str) -> Result<Vec<u32>> {
    let loc = where_(acc, what);
    expect(acc, dims, &loc)?;
    if !matches!(acc.data_type(), DataType::U8 | DataType::U16 | DataType::U32) || acc.normalized() {
        return Err(Error::invalid(
            loc,
            format!(
                "expected unsigned integers, found {:?}{}",
                acc.data_type(),
                if acc.normalized() { " (normalized)" } else { "" }
            ),
        ));
    }
    Ok(read_f64(acc, buffers, &loc)?.into_iter().map(|x| x as u32).collect())
}
