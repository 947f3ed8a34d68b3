//! Values as the scene file writes them, and their checks: fixed-length arrays, colours,
//! finite vectors and numbers in range, keys that a type takes or requires. Every check
//! returns a [`Problem`]: where in the source, and what is wrong.

use std::ops::Range;

use glam::DVec3;

use crate::limits::{MAX_LENGTH, MAX_RADIANCE};
use serde::Deserialize;
use toml::Spanned;

/// A TOML array of exactly `N` values. (serde's `[T; N]` lets the toml deserializer drop
/// extra elements silently.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Array<T, const N: usize>(pub(super) [T; N]);

impl<'de, T: Deserialize<'de>, const N: usize> Deserialize<'de> for Array<T, N> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T, const N: usize>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>, const N: usize> serde::de::Visitor<'de> for V<T, N> {
            type Value = Array<T, N>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "an array of {N} elements")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Self::Value, A::Error> {
                let mut v = Vec::with_capacity(N);
                while let Some(x) = seq.next_element()? {
                    v.push(x);
                }
                let n = v.len();
                v.try_into()
                    .map(Array)
                    .map_err(|_| serde::de::Error::invalid_length(n, &self))
            }
        }
        d.deserialize_seq(V(std::marker::PhantomData))
    }
}

/// An RGB colour: `[r, g, b]`, or one number for grey.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Colour(pub(super) DVec3);

impl<'de> Deserialize<'de> for Colour {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Colour;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "a number or an array [r, g, b]")
            }
            fn visit_f64<E>(self, x: f64) -> Result<Colour, E> {
                Ok(Colour(DVec3::splat(x)))
            }
            fn visit_i64<E>(self, x: i64) -> Result<Colour, E> {
                Ok(Colour(DVec3::splat(x as f64)))
            }
            fn visit_u64<E>(self, x: u64) -> Result<Colour, E> {
                Ok(Colour(DVec3::splat(x as f64)))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, seq: A) -> Result<Colour, A::Error> {
                let a: Array<f64, 3> =
                    Deserialize::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))?;
                Ok(Colour(DVec3::from_array(a.0)))
            }
        }
        d.deserialize_any(V)
    }
}

/// The value of a spanned array.
/// A number or an array of numbers (`xray_mu = 2` or `xray_mu = [3, 2, 1.5]`).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Numbers(pub(super) Vec<f64>);

impl<'de> Deserialize<'de> for Numbers {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Numbers;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "a number or an array of numbers")
            }
            fn visit_f64<E>(self, x: f64) -> Result<Numbers, E> {
                Ok(Numbers(vec![x]))
            }
            fn visit_i64<E>(self, x: i64) -> Result<Numbers, E> {
                Ok(Numbers(vec![x as f64]))
            }
            fn visit_u64<E>(self, x: u64) -> Result<Numbers, E> {
                Ok(Numbers(vec![x as f64]))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Numbers, A::Error> {
                let mut v = Vec::new();
                while let Some(x) = seq.next_element()? {
                    v.push(x);
                }
                Ok(Numbers(v))
            }
        }
        d.deserialize_any(V)
    }
}

pub(super) fn val<T: Copy, const N: usize>(s: &Spanned<Array<T, N>>) -> [T; N] {
    s.get_ref().0
}

/// A validation failure: where (bytes of the source) and what.
pub(super) type Problem = (Range<usize>, String);

/// `[x, y, z]` for a message, each number at most 12 digits.
fn show(v: [f64; 3]) -> String {
    format!("[{}]", v.map(gencyl::limits::short).join(", "))
}

/// A point: a finite 3-vector with coordinates up to [`MAX_LENGTH`] in magnitude.
pub(super) fn vec3(s: &Spanned<Array<f64, 3>>, what: &str) -> Result<DVec3, Problem> {
    let v = DVec3::from_array(val(s));
    if !v.is_finite() {
        Err((
            s.span(),
            format!("{what} must be finite, got {}", show(val(s))),
        ))
    } else if v.abs().max_element() > MAX_LENGTH {
        Err((
            s.span(),
            format!(
                "{what} {} is beyond {MAX_LENGTH:.0e} from the origin: {}",
                show(val(s)),
                gencyl::limits::WHY_COORDINATE
            ),
        ))
    } else {
        Ok(v)
    }
}

/// A direction: a finite non-zero 3-vector of any length, normalized (scaled by its largest
/// component first, so that neither `[1e200, 0, 0]` nor `[1e-200, 0, 0]` squares out of range).
pub(super) fn direction(s: &Spanned<Array<f64, 3>>, what: &str) -> Result<DVec3, Problem> {
    let v = DVec3::from_array(val(s));
    if !v.is_finite() {
        return Err((
            s.span(),
            format!("{what} must be finite, got {}", show(val(s))),
        ));
    }
    let big = v.abs().max_element();
    if big > 0.0 {
        Ok((v / big).normalize())
    } else {
        Err((s.span(), format!("{what} must not be zero")))
    }
}

/// A length: positive, at most [`MAX_LENGTH`].
pub(super) fn length(s: &Spanned<f64>, what: &str) -> Result<f64, Problem> {
    number(s, what, 0.0, MAX_LENGTH, true)
}

/// A finite number in `[lo, hi]` (`open`: excluding `lo`).
pub(super) fn number(
    s: &Spanned<f64>,
    what: &str,
    lo: f64,
    hi: f64,
    open: bool,
) -> Result<f64, Problem> {
    check_number(*s.get_ref(), what, lo, hi, open).map_err(|m| (s.span(), m))
}

/// [`number`] without a place in the source.
pub(super) fn check_number(
    x: f64,
    what: &str,
    lo: f64,
    hi: f64,
    open: bool,
) -> Result<f64, String> {
    let ok = x.is_finite() && x <= hi && if open { x > lo } else { x >= lo };
    if ok {
        return Ok(x);
    }
    let hi_text = if hi >= 1e6 {
        format!("{hi:e}")
    } else {
        format!("{hi}")
    };
    let range = match (open, hi.is_finite()) {
        (true, false) if lo == 0.0 => "positive and finite".to_string(),
        (false, false) if lo == 0.0 => "non-negative and finite".to_string(),
        (true, _) if lo == 0.0 && hi == MAX_LENGTH => format!("positive and at most {hi_text}"),
        (true, _) => format!("in ({lo}, {hi_text}]"),
        (false, _) => format!("in [{lo}, {hi_text}]"),
    };
    Err(format!(
        "{what} must be {range}, got {}",
        gencyl::limits::short(x)
    ))
}

/// A finite non-negative colour.
pub(super) fn colour(s: &Spanned<Colour>, what: &str) -> Result<DVec3, Problem> {
    let c = s.get_ref().0;
    if c.is_finite() && c.min_element() >= 0.0 {
        Ok(c)
    } else {
        Err((
            s.span(),
            format!(
                "{what} must be finite and non-negative, got {}",
                show(c.to_array())
            ),
        ))
    }
}

/// A light's or the sky's value: a colour of at most [`MAX_RADIANCE`].
pub(super) fn radiance(s: &Spanned<Colour>, what: &str) -> Result<DVec3, Problem> {
    let c = colour(s, what)?;
    if c.max_element() > MAX_RADIANCE {
        return Err((
            s.span(),
            format!(
                "{what} {} is above {MAX_RADIANCE:.0e}: sums of samples of it would overflow the image",
                show(c.to_array())
            ),
        ));
    }
    Ok(c)
}

/// `key` must be absent for `kind` (a light or material type).
pub(super) fn not_for<T>(key: &Option<Spanned<T>>, name: &str, kind: &str) -> Result<(), Problem> {
    match key {
        Some(k) => Err((k.span(), format!("`{name}` does not apply to {kind}"))),
        None => Ok(()),
    }
}

/// A required key.
pub(super) fn required<'a, T>(
    key: &'a Option<Spanned<T>>,
    name: &str,
    kind: &str,
    table: &Range<usize>,
) -> Result<&'a Spanned<T>, Problem> {
    key.as_ref()
        .ok_or_else(|| (table.clone(), format!("{kind} needs `{name}`")))
}

/// Where a key's value is, if it is there.
pub(super) fn span_of<T>(k: &Option<Spanned<T>>) -> Option<Range<usize>> {
    k.as_ref().map(Spanned::span)
}

/// Every key present must be one `kind` takes: `keys` pairs names with where their values are.
pub(super) fn only_keys(
    keys: &[(&str, Option<Range<usize>>)],
    allowed: &[&str],
    kind: &str,
) -> Result<(), Problem> {
    for (name, span) in keys {
        if let Some(span) = span
            && !allowed.contains(name)
        {
            return Err((span.clone(), format!("`{name}` does not apply to {kind}")));
        }
    }
    Ok(())
}
