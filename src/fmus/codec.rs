//! The muscle FMUs' state codec: a serialized state is a [`Wire`] value, a
//! plain struct whose fields are listed once, in byte order
//! ([`wire_struct!`]); that one list drives both [`Wire::encode`] and
//! [`Wire::decode`] over [`crate::fmi2::bytes`]. Decoding only reads bytes:
//! each model checks the decoded value separately (is it a state some call
//! sequence reaches?) before it builds anything from it.
//!
//! Invariants: a count prefix is bounded by the bytes left (each element
//! takes at least [`Wire::MIN_BYTES`]), so no decode allocates more than its
//! input justifies; a decode error names the field path it failed at.

use crate::fmi2::bytes::{ByteError, ByteReader, ByteWriter};
use crate::fmi2::{Model, ModelError, ScalarVariable};
use crate::scene::{SceneSpec, Value};

/// A value with a fixed little-endian byte form.
pub trait Wire: Sized {
    /// The fewest bytes an encoded value takes.
    const MIN_BYTES: usize;
    fn encode(&self, w: &mut ByteWriter<'_>);
    fn decode(r: &mut ByteReader<'_, '_>) -> Result<Self, ByteError>;
}

macro_rules! scalar_wire {
    ($($ty:ty => $bytes:expr, $method:ident;)*) => {$(
        impl Wire for $ty {
            const MIN_BYTES: usize = $bytes;
            fn encode(&self, w: &mut ByteWriter<'_>) {
                w.$method(*self);
            }
            fn decode(r: &mut ByteReader<'_, '_>) -> Result<Self, ByteError> {
                r.$method()
            }
        }
    )*};
}

scalar_wire! {
    f64 => 8, f64;
    bool => 1, bool;
    i32 => 4, i32;
    u64 => 8, u64;
}

/// A `u64` count, then the elements (for `f64` the layout of
/// [`ByteWriter::f64s`]).
impl<T: Wire> Wire for Vec<T> {
    const MIN_BYTES: usize = 8;
    fn encode(&self, w: &mut ByteWriter<'_>) {
        w.u64(self.len() as u64);
        for x in self {
            x.encode(w);
        }
    }
    fn decode(r: &mut ByteReader<'_, '_>) -> Result<Self, ByteError> {
        let n = r.u64()?;
        let most = r.remaining() / T::MIN_BYTES.max(1);
        if n > most as u64 {
            return Err(ByteError(format!(
                "{n} elements cannot fit in the {} remaining bytes",
                r.remaining()
            )));
        }
        (0..n).map(|_| T::decode(r)).collect()
    }
}

/// A flag, then the value when it is set.
impl<T: Wire> Wire for Option<T> {
    const MIN_BYTES: usize = 1;
    fn encode(&self, w: &mut ByteWriter<'_>) {
        w.bool(self.is_some());
        if let Some(x) = self {
            x.encode(w);
        }
    }
    fn decode(r: &mut ByteReader<'_, '_>) -> Result<Self, ByteError> {
        if r.bool()? {
            T::decode(r).map(Some)
        } else {
            Ok(None)
        }
    }
}

/// Exactly `N` values, count-prefixed like a `Vec<f64>`.
impl<const N: usize> Wire for [f64; N] {
    const MIN_BYTES: usize = 8 + 8 * N;
    fn encode(&self, w: &mut ByteWriter<'_>) {
        w.f64s(self);
    }
    fn decode(r: &mut ByteReader<'_, '_>) -> Result<Self, ByteError> {
        let v = r.f64s()?;
        let n = v.len();
        v.try_into()
            .map_err(|_| ByteError(format!("{n} values, expected {N}")))
    }
}

/// An optional `f64` written as a list of zero or one values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaybeF64(pub Option<f64>);

impl Wire for MaybeF64 {
    const MIN_BYTES: usize = 8;
    fn encode(&self, w: &mut ByteWriter<'_>) {
        w.f64s(self.0.as_slice());
    }
    fn decode(r: &mut ByteReader<'_, '_>) -> Result<Self, ByteError> {
        match r.f64s()?.as_slice() {
            [] => Ok(MaybeF64(None)),
            &[x] => Ok(MaybeF64(Some(x))),
            other => Err(ByteError(format!(
                "{} values, expected at most 1",
                other.len()
            ))),
        }
    }
}

/// A struct of [`Wire`] fields encoded in the order they are listed; a
/// decode error is prefixed with the field's name.
macro_rules! wire_struct {
    ($(#[$meta:meta])* $vis:vis struct $name:ident {
        $($(#[$fmeta:meta])* $field:ident : $ty:ty),* $(,)?
    }) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq)]
        $vis struct $name {
            $($(#[$fmeta])* pub $field: $ty),*
        }

        impl $crate::fmus::codec::Wire for $name {
            const MIN_BYTES: usize =
                0 $(+ <$ty as $crate::fmus::codec::Wire>::MIN_BYTES)*;
            fn encode(&self, w: &mut $crate::fmi2::bytes::ByteWriter<'_>) {
                $($crate::fmus::codec::Wire::encode(&self.$field, w);)*
            }
            fn decode(
                r: &mut $crate::fmi2::bytes::ByteReader<'_, '_>,
            ) -> Result<Self, $crate::fmi2::bytes::ByteError> {
                // Struct expressions evaluate their fields in the order written.
                Ok($name {
                    $($field: $crate::fmus::codec::Wire::decode(r).map_err(|e| {
                        $crate::fmi2::bytes::ByteError(
                            format!("{}: {}", stringify!($field), e.0),
                        )
                    })?,)*
                })
            }
        }
    };
}
pub(crate) use wire_struct;

/// `value` written by [`Wire::encode`] onto `out`.
pub fn encode_onto<T: Wire>(value: &T, out: &mut Vec<u8>) {
    value.encode(&mut ByteWriter::new(out));
}

/// A [`Wire`] value read from `input` (advanced past it); errors prefixed
/// with `model`'s name.
pub fn decode_from<T: Wire>(model: &str, input: &mut &[u8]) -> Result<T, ModelError> {
    T::decode(&mut ByteReader::new(input)).map_err(|e| ModelError(format!("{model} state: {e}")))
}

/// A restored model's parameters that scene `spec` compiles in as constants
/// (no call can change them) equal to the compiled-in values; `all` is the
/// variant's complete variable table. The error names the first that does
/// not.
pub fn check_scene_constants<M: Model>(
    spec: &SceneSpec,
    all: &[ScalarVariable<M::Var>],
    m: &M,
) -> Result<(), String> {
    for s in spec.parameters.iter().filter(|s| s.constant) {
        let Some(v) = all.iter().find(|v| v.name == s.name) else {
            continue;
        };
        let restored = match s.value {
            Value::Real(x) => (m.get_real(v.id) != x).then(|| Value::Real(m.get_real(v.id))),
            Value::Integer(i) => {
                (m.get_integer(v.id) != i).then(|| Value::Integer(m.get_integer(v.id)))
            }
            Value::Boolean(b) => {
                (m.get_boolean(v.id) != b).then(|| Value::Boolean(m.get_boolean(v.id)))
            }
        };
        if let Some(restored) = restored {
            return Err(format!(
                "{} = {restored}, but scene {} compiles it in as the constant {}",
                s.name, spec.model_identifier, s.value
            ));
        }
    }
    Ok(())
}

/// `stored` equal to `recomputed` (bit for bit, NaN never), else an error
/// naming output `name`.
pub fn check_output(name: &str, stored: f64, recomputed: f64) -> Result<(), String> {
    if stored.to_bits() == recomputed.to_bits() && !stored.is_nan() {
        Ok(())
    } else {
        Err(format!(
            "output {name} = {stored} is not that of the restored state ({recomputed})"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    wire_struct! {
        struct Inner {
            a: f64,
            b: Vec<f64>,
        }
    }

    wire_struct! {
        struct Outer {
            flag: bool,
            n: i32,
            inner: Option<Inner>,
            many: Vec<Inner>,
            one: MaybeF64,
            four: [f64; 4],
        }
    }

    fn sample() -> Outer {
        Outer {
            flag: true,
            n: -3,
            inner: Some(Inner {
                a: 1.5,
                b: vec![2.0, -0.0],
            }),
            many: vec![Inner { a: 3.0, b: vec![] }],
            one: MaybeF64(Some(4.0)),
            four: [1.0, 2.0, 3.0, 4.0],
        }
    }

    /// The listed order is the byte order, and a value round-trips.
    #[test]
    fn fields_are_written_in_the_listed_order_and_read_back() {
        let mut bytes = Vec::new();
        encode_onto(&sample(), &mut bytes);
        let mut expected = Vec::new();
        ByteWriter::new(&mut expected)
            .bool(true)
            .i32(-3)
            .bool(true)
            .f64(1.5)
            .f64s(&[2.0, -0.0])
            .u64(1)
            .f64(3.0)
            .f64s(&[])
            .f64s(&[4.0])
            .f64s(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(bytes, expected);
        let mut input = bytes.as_slice();
        assert_eq!(decode_from::<Outer>("T", &mut input).unwrap(), sample());
        assert!(input.is_empty());
    }

    /// A count larger than the remaining bytes can hold is refused before
    /// anything is allocated, the error naming the field; so is a wrong
    /// fixed length.
    #[test]
    fn counts_are_bounded_by_the_remaining_bytes_and_errors_name_the_field() {
        let mut bytes = Vec::new();
        ByteWriter::new(&mut bytes)
            .bool(true)
            .i32(0)
            .bool(false)
            .u64(u64::MAX / 2);
        let e = decode_from::<Outer>("T", &mut bytes.as_slice()).unwrap_err();
        assert!(e.0.starts_with("T state: many: "), "{}", e.0);
        assert!(e.0.contains("cannot fit"), "{}", e.0);
        let mut bytes = Vec::new();
        let mut s = sample();
        s.inner = None;
        s.many.clear();
        encode_onto(&s, &mut bytes);
        // Cut the last array to 3 values.
        let n = bytes.len();
        bytes.truncate(n - 8 * 5);
        ByteWriter::new(&mut bytes).f64s(&[1.0, 2.0, 3.0]);
        let e = decode_from::<Outer>("T", &mut bytes.as_slice()).unwrap_err();
        assert_eq!(e.0, "T state: four: 3 values, expected 4");
    }
}
