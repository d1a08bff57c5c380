//! Little-endian byte helpers for serialized FMU states
//! (`fmi2SerializeFMUstate` / `fmi2DeSerializeFMUstate`, FMI 2.0 spec,
//! section 2.1.8).
//!
//! Serialized states hold values only, never pointers, in a fixed byte order,
//! so a state written by one process restores in another. The layer uses
//! these helpers for its own header and fields; models use them in
//! [`Model::serialize`](super::Model::serialize) and
//! [`Model::deserialize`](super::Model::deserialize):
//!
//! ```
//! use hill_muscle::fmi2::bytes::{ByteReader, ByteWriter};
//! let mut buf = Vec::new();
//! ByteWriter::new(&mut buf).f64(1.5).u32(7).bool(true);
//! let mut input: &[u8] = &buf;
//! let mut r = ByteReader::new(&mut input);
//! assert_eq!(r.f64().unwrap(), 1.5);
//! assert_eq!(r.u32().unwrap(), 7);
//! assert!(r.bool().unwrap());
//! assert!(r.is_empty());
//! ```

use std::fmt;

/// Appends values to a byte vector in little-endian order.
pub struct ByteWriter<'a> {
    out: &'a mut Vec<u8>,
}

impl<'a> ByteWriter<'a> {
    pub fn new(out: &'a mut Vec<u8>) -> Self {
        ByteWriter { out }
    }

    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.out.push(v);
        self
    }

    pub fn bool(&mut self, v: bool) -> &mut Self {
        self.u8(u8::from(v))
    }

    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.out.extend_from_slice(&v.to_le_bytes());
        self
    }

    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.out.extend_from_slice(&v.to_le_bytes());
        self
    }

    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.out.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// The IEEE-754 bit pattern (NaN payloads and signed zeros survive).
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.u64(v.to_bits())
    }

    /// A `u64` length followed by the bytes.
    pub fn bytes(&mut self, v: &[u8]) -> &mut Self {
        self.u64(v.len() as u64);
        self.out.extend_from_slice(v);
        self
    }

    /// A length-prefixed UTF-8 string.
    pub fn str(&mut self, v: &str) -> &mut Self {
        self.bytes(v.as_bytes())
    }

    /// A `u64` count followed by the values.
    pub fn f64s(&mut self, v: &[f64]) -> &mut Self {
        self.u64(v.len() as u64);
        for &x in v {
            self.f64(x);
        }
        self
    }

    /// Raw bytes without a length prefix.
    pub fn raw(&mut self, v: &[u8]) -> &mut Self {
        self.out.extend_from_slice(v);
        self
    }
}

/// Error of a [`ByteReader`]: truncated or malformed input.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ByteError(pub String);

impl fmt::Display for ByteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ByteError {}

/// Lets `?` turn a [`ByteError`] into a [`ModelError`](super::ModelError)
/// (through `ModelError`'s `From<impl Into<String>>`).
impl From<ByteError> for String {
    fn from(e: ByteError) -> String {
        e.0
    }
}

/// Reads values written by [`ByteWriter`], advancing the borrowed slice (so
/// the caller's `&mut &[u8]` points past what was read). Every read checks
/// the remaining length first: truncated input is an error, never a panic.
pub struct ByteReader<'a, 'b> {
    input: &'b mut &'a [u8],
}

impl<'a, 'b> ByteReader<'a, 'b> {
    pub fn new(input: &'b mut &'a [u8]) -> Self {
        ByteReader { input }
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.input.len()
    }

    pub fn is_empty(&self) -> bool {
        self.input.is_empty()
    }

    /// Error unless everything was read.
    pub fn expect_end(&self) -> Result<(), ByteError> {
        if self.input.is_empty() {
            Ok(())
        } else {
            Err(ByteError(format!(
                "{} unexpected trailing bytes",
                self.input.len()
            )))
        }
    }

    /// The next `n` bytes.
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], ByteError> {
        if n > self.input.len() {
            return Err(ByteError(format!(
                "truncated: {n} bytes needed, {} left",
                self.input.len()
            )));
        }
        let (head, tail) = self.input.split_at(n);
        *self.input = tail;
        Ok(head)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], ByteError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }

    pub fn u8(&mut self) -> Result<u8, ByteError> {
        Ok(self.array::<1>()?[0])
    }

    /// Accepts only 0 and 1.
    pub fn bool(&mut self) -> Result<bool, ByteError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(ByteError(format!("invalid boolean byte {v}"))),
        }
    }

    pub fn u32(&mut self) -> Result<u32, ByteError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    pub fn i32(&mut self) -> Result<i32, ByteError> {
        Ok(i32::from_le_bytes(self.array()?))
    }

    pub fn u64(&mut self) -> Result<u64, ByteError> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    pub fn f64(&mut self) -> Result<f64, ByteError> {
        Ok(f64::from_bits(self.u64()?))
    }

    /// A length prefix, checked against the remaining input (so a corrupt
    /// length never causes a huge allocation). `elem` is the element size.
    fn len(&mut self, elem: usize) -> Result<usize, ByteError> {
        let n = self.u64()?;
        let fits = usize::try_from(n)
            .ok()
            .and_then(|n| n.checked_mul(elem))
            .is_some_and(|bytes| bytes <= self.input.len());
        if !fits {
            return Err(ByteError(format!(
                "length {n} exceeds the {} remaining bytes",
                self.input.len()
            )));
        }
        Ok(n as usize)
    }

    /// Length-prefixed bytes.
    pub fn bytes(&mut self) -> Result<&'a [u8], ByteError> {
        let n = self.len(1)?;
        self.take(n)
    }

    /// Length-prefixed UTF-8 string.
    pub fn str(&mut self) -> Result<&'a str, ByteError> {
        let b = self.bytes()?;
        std::str::from_utf8(b).map_err(|e| ByteError(format!("invalid UTF-8: {e}")))
    }

    /// Count-prefixed `f64` values.
    pub fn f64s(&mut self) -> Result<Vec<f64>, ByteError> {
        let n = self.len(8)?;
        (0..n).map(|_| self.f64()).collect()
    }
}

/// 64-bit FNV-1a hash (used for the checksum of serialized states and the
/// GUID). `seed` is the offset basis.
pub fn fnv1a64(seed: u64, data: &[u8]) -> u64 {
    let mut h = seed;
    for &b in data {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The standard FNV-1a 64-bit offset basis.
pub const FNV64_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_truncation() {
        let mut buf = Vec::new();
        ByteWriter::new(&mut buf)
            .u8(3)
            .bool(false)
            .u32(0xdead_beef)
            .i32(-5)
            .u64(u64::MAX)
            .f64(-0.0)
            .str("héllo")
            .f64s(&[1.0, f64::INFINITY]);
        let mut input: &[u8] = &buf;
        let mut r = ByteReader::new(&mut input);
        assert_eq!(r.u8().unwrap(), 3);
        assert!(!r.bool().unwrap());
        assert_eq!(r.u32().unwrap(), 0xdead_beef);
        assert_eq!(r.i32().unwrap(), -5);
        assert_eq!(r.u64().unwrap(), u64::MAX);
        assert_eq!(r.f64().unwrap().to_bits(), (-0.0f64).to_bits());
        assert_eq!(r.str().unwrap(), "héllo");
        assert_eq!(r.f64s().unwrap(), vec![1.0, f64::INFINITY]);
        r.expect_end().unwrap();

        for cut in 0..buf.len() {
            let mut input: &[u8] = &buf[..cut];
            let mut r = ByteReader::new(&mut input);
            let res = (|| -> Result<(), ByteError> {
                r.u8()?;
                r.bool()?;
                r.u32()?;
                r.i32()?;
                r.u64()?;
                r.f64()?;
                r.str()?;
                r.f64s()?;
                Ok(())
            })();
            assert!(res.is_err(), "cut at {cut} must fail");
        }
    }

    #[test]
    fn huge_length_rejected() {
        let mut buf = Vec::new();
        ByteWriter::new(&mut buf).u64(u64::MAX);
        let mut input: &[u8] = &buf;
        assert!(ByteReader::new(&mut input).bytes().is_err());
        let mut input: &[u8] = &buf;
        assert!(ByteReader::new(&mut input).f64s().is_err());
    }
}
