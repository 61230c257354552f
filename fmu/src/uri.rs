//! The `fmuResourceLocation` URI of fmi2Instantiate (FMI 2.0 §2.1.6): a
//! `file` URI of the unzipped `resources` directory. Importers write it as
//! `file:///dir/` (RFC 8089), `file:/dir` (RFC 1738 short form, e.g. FMPy
//! on some versions) or `file://localhost/dir`, percent-encoded, with or
//! without a trailing slash.

use std::ffi::OsString;
use std::os::unix::ffi::OsStringExt;
use std::path::PathBuf;

/// Why a resource location cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum UriError {
    /// Not a `file:` URI.
    #[error("resource location '{0}' is not a file: URI")]
    NotFile(String),
    /// A `file://host/...` URI naming a host other than localhost.
    #[error("resource location '{uri}' names host '{host}': only local files are supported")]
    RemoteHost {
        /// The URI.
        uri: String,
        /// The host it names.
        host: String,
    },
    /// The path is not absolute.
    #[error("resource location '{0}' has no absolute path")]
    Relative(String),
    /// A `%` not followed by two hex digits.
    #[error("resource location '{0}' has a malformed percent-encoding")]
    BadEscape(String),
}

/// The directory a `file` URI names.
pub fn resource_directory(uri: &str) -> Result<PathBuf, UriError> {
    let rest = uri
        .get(..5)
        .filter(|scheme| scheme.eq_ignore_ascii_case("file:"))
        .map(|_| &uri[5..])
        .ok_or_else(|| UriError::NotFile(uri.to_string()))?;
    let path = match rest.strip_prefix("//") {
        Some(authority_and_path) => {
            let slash = authority_and_path.find('/').unwrap_or(authority_and_path.len());
            let host = &authority_and_path[..slash];
            if !(host.is_empty() || host.eq_ignore_ascii_case("localhost")) {
                return Err(UriError::RemoteHost { uri: uri.to_string(), host: host.to_string() });
            }
            &authority_and_path[slash..]
        }
        None => rest,
    };
    if !path.starts_with('/') {
        return Err(UriError::Relative(uri.to_string()));
    }
    let bytes = percent_decode(path).ok_or_else(|| UriError::BadEscape(uri.to_string()))?;
    Ok(PathBuf::from(OsString::from_vec(bytes)))
}

/// Decodes `%XX` escapes; `None` for a malformed one.
fn percent_decode(text: &str) -> Option<Vec<u8>> {
    let bytes = text.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            decoded.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            decoded.push(bytes[i]);
            i += 1;
        }
    }
    Some(decoded)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(uri: &str) -> PathBuf {
        resource_directory(uri).unwrap_or_else(|e| panic!("{uri}: {e}"))
    }

    #[test]
    fn accepts_the_usual_forms() {
        assert_eq!(dir("file:///tmp/fmu/resources/"), PathBuf::from("/tmp/fmu/resources/"));
        assert_eq!(dir("file:///tmp/fmu/resources"), PathBuf::from("/tmp/fmu/resources"));
        assert_eq!(dir("file:/tmp/fmu/resources"), PathBuf::from("/tmp/fmu/resources"));
        assert_eq!(dir("file://localhost/tmp/r/"), PathBuf::from("/tmp/r/"));
        assert_eq!(dir("FILE:///tmp/r"), PathBuf::from("/tmp/r"));
    }

    #[test]
    fn decodes_percent_escapes() {
        assert_eq!(dir("file:///tmp/my%20fmu/res%C3%A9/"), PathBuf::from("/tmp/my fmu/resé/"));
        assert_eq!(dir("file:///tmp/100%25"), PathBuf::from("/tmp/100%"));
    }

    #[test]
    fn rejects_what_is_not_a_local_file() {
        assert!(matches!(resource_directory("http://x/y"), Err(UriError::NotFile(_))));
        assert!(matches!(resource_directory("/tmp/r"), Err(UriError::NotFile(_))));
        assert!(matches!(resource_directory(""), Err(UriError::NotFile(_))));
        assert!(matches!(resource_directory("file://server/share"), Err(UriError::RemoteHost { .. })));
        assert!(matches!(resource_directory("file:relative/dir"), Err(UriError::Relative(_))));
        assert!(matches!(resource_directory("file:///tmp/%2"), Err(UriError::BadEscape(_))));
        assert!(matches!(resource_directory("file:///tmp/%zz"), Err(UriError::BadEscape(_))));
    }
}
