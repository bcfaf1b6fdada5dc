//! Serde helpers of the JSON documents (`result.json`): how a number that may be
//! non-finite is written and read.

/// An `f64` that JSON writes as `null` when it is NaN or infinite (JSON has no such
/// numbers) and reads back from `null` as NaN: `#[serde(with = "nan_as_null")]`.
pub mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    /// The number, or `null` when it is not finite.
    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }

    /// A number, or NaN for `null`.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn non_finite_numbers_are_null_and_null_is_nan() {
        #[derive(serde::Serialize, serde::Deserialize)]
        struct Doc {
            #[serde(with = "super::nan_as_null")]
            x: f64,
        }
        let text = serde_json::to_string(&Doc { x: f64::INFINITY }).unwrap();
        assert_eq!(text, r#"{"x":null}"#);
        assert!(serde_json::from_str::<Doc>(&text).unwrap().x.is_nan());
        let back: Doc = serde_json::from_str(r#"{"x":0.25}"#).unwrap();
        assert_eq!(back.x, 0.25);
    }
}
