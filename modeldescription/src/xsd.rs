//! Serde helpers for the XML Schema spellings FMI 2.0 uses that serde's
//! defaults (through quick-xml) do not produce by themselves.

/// `xs:double` attributes held as `Option<f64>`.
///
/// quick-xml writes floats with `Display`, which never uses an exponent
/// (1e-300 becomes a 302-character string) and spells infinity `inf`, which
/// is not an `xs:double`. This writes the shortest decimal that parses back
/// to the same `f64` (Rust's `Display`/`LowerExp` are both shortest
/// round-trip), switching to exponent notation outside a readable range, and
/// uses the XML Schema spellings `INF`, `-INF`, `NaN`.
pub(crate) mod optional_double {
    use serde::{Deserialize, Deserializer, Serializer, de::Error as _};
    use std::fmt;

    pub(crate) struct XsdDouble(pub(crate) f64);

    impl fmt::Display for XsdDouble {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            let x = self.0;
            if x.is_nan() {
                f.write_str("NaN")
            } else if x.is_infinite() {
                f.write_str(if x > 0.0 { "INF" } else { "-INF" })
            } else if x == 0.0 || (1e-5..1e16).contains(&x.abs()) {
                write!(f, "{x}")
            } else {
                write!(f, "{x:e}")
            }
        }
    }

    pub(crate) fn serialize<S: Serializer>(value: &Option<f64>, serializer: S) -> Result<S::Ok, S::Error> {
        match value {
            Some(x) => serializer.collect_str(&XsdDouble(*x)),
            None => serializer.serialize_none(),
        }
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Option<f64>, D::Error> {
        let text = String::deserialize(deserializer)?;
        // Rust's parser accepts every xs:double lexical form, including
        // `INF`/`-INF`/`NaN` (it matches those case-insensitively).
        text.trim().parse().map(Some).map_err(|_| D::Error::custom(format!("`{text}` is not an xs:double")))
    }
}

/// `xs:double` lists (FMI 3.0 array start values) held as `Option<Vec<f64>>`:
/// space-separated, each value spelled as [`optional_double`] spells one.
pub(crate) mod double_list {
    use serde::{Deserialize, Deserializer, Serializer, de::Error as _};

    use super::optional_double::XsdDouble;

    pub(crate) fn serialize<S: Serializer>(values: &Option<Vec<f64>>, serializer: S) -> Result<S::Ok, S::Error> {
        match values {
            Some(values) => {
                let text: Vec<String> = values.iter().map(|&x| XsdDouble(x).to_string()).collect();
                serializer.serialize_str(&text.join(" "))
            }
            None => serializer.serialize_none(),
        }
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Option<Vec<f64>>, D::Error> {
        let text = String::deserialize(deserializer)?;
        let values: Result<Vec<f64>, _> = text.split_whitespace().map(str::parse).collect();
        values.map(Some).map_err(|_| D::Error::custom(format!("`{text}` is not a list of xs:double")))
    }
}

/// Defines a serde `with` module for a `Vec` written as one wrapper element
/// holding one child element per item, e.g.
/// `<UnitDefinitions><Unit/><Unit/></UnitDefinitions>`.
///
/// Keeping the wrapper out of the public types lets the model hold plain
/// `Vec`s; an empty `Vec` is skipped by the field's `skip_serializing_if`,
/// which the schema requires wherever the wrapper element needs at least
/// one child.
macro_rules! wrapped_list {
    ($module:ident, $item:ty, $child:literal) => {
        pub(crate) mod $module {
            use serde::{Deserialize, Deserializer, Serialize, Serializer};

            #[derive(Serialize)]
            struct Wrapper<'a> {
                #[serde(rename = $child)]
                items: &'a [$item],
            }

            #[derive(Deserialize)]
            struct OwnedWrapper {
                #[serde(rename = $child, default)]
                items: Vec<$item>,
            }

            pub(crate) fn serialize<S: Serializer>(items: &[$item], serializer: S) -> Result<S::Ok, S::Error> {
                Wrapper { items }.serialize(serializer)
            }

            pub(crate) fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<$item>, D::Error> {
                Ok(OwnedWrapper::deserialize(deserializer)?.items)
            }
        }
    };
}

wrapped_list!(unit_definitions, crate::Unit, "Unit");
wrapped_list!(type_definitions, crate::SimpleType, "SimpleType");
wrapped_list!(log_categories, crate::Category, "Category");
wrapped_list!(model_variables, crate::ScalarVariable, "ScalarVariable");
wrapped_list!(unknowns, crate::Unknown, "Unknown");
