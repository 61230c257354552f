//! The `fmuResourceLocation` URI of fmi2Instantiate (FMI 2.0 §2.1.6): a
//! `file` URI of the unzipped `resources` directory. Importers write it as
//! `file:///dir/` (RFC 8089), `file:/dir` (RFC 1738 short form, e.g. FMPy
//! on some versions) or `file://localhost/dir`, percent-encoded, with or
//! without a trailing slash. On Windows the path carries a drive
//! (`file:///C:/dir`, also the common non-standard `file://C:/dir` and
//! `file:///C|/dir`) or names a share (`file://server/share/dir` or
//! `file:////server/share/dir`, the UNC path `\\server\share\dir`).
//!
//! The parsing is the same code on every platform, told which platform's
//! paths to produce, so both kinds are tested wherever the tests run.

use std::path::PathBuf;

/// Why a resource location cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum UriError {
    /// Not a `file:` URI.
    #[error("resource location '{0}' is not a file: URI")]
    NotFile(String),
    /// A `file://host/...` URI naming a host other than localhost (on
    /// Windows, a share without a name or path).
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
    /// On Windows, the decoded path is not UTF-8 (Windows paths are Unicode).
    #[error("resource location '{0}' decodes to a path that is not UTF-8")]
    NotUtf8(String),
}

/// Whose path syntax a URI is turned into.
#[derive(Clone, Copy, Debug, PartialEq)]
enum PathSyntax {
    /// `/dir/sub`, any bytes.
    Unix,
    /// `C:\dir\sub` or `\\server\share\sub`, Unicode.
    Windows,
}

const HOST_SYNTAX: PathSyntax = if cfg!(windows) { PathSyntax::Windows } else { PathSyntax::Unix };

/// The directory a `file` URI names, as a path of this platform.
pub fn resource_directory(uri: &str) -> Result<PathBuf, UriError> {
    let bytes = local_path(uri, HOST_SYNTAX)?;
    native_path(bytes).ok_or_else(|| UriError::NotUtf8(uri.to_string()))
}

#[cfg(unix)]
fn native_path(bytes: Vec<u8>) -> Option<PathBuf> {
    use std::os::unix::ffi::OsStringExt;
    Some(PathBuf::from(std::ffi::OsString::from_vec(bytes)))
}

#[cfg(not(unix))]
fn native_path(bytes: Vec<u8>) -> Option<PathBuf> {
    String::from_utf8(bytes).ok().map(PathBuf::from)
}

/// The path a `file` URI names, in `syntax`, as bytes (UTF-8 on Windows,
/// checked by the caller).
fn local_path(uri: &str, syntax: PathSyntax) -> Result<Vec<u8>, UriError> {
    let rest = uri
        .get(..5)
        .filter(|scheme| scheme.eq_ignore_ascii_case("file:"))
        .map(|_| &uri[5..])
        .ok_or_else(|| UriError::NotFile(uri.to_string()))?;
    let decode = |text: &str| percent_decode(text).ok_or_else(|| UriError::BadEscape(uri.to_string()));
    let Some(authority_and_path) = rest.strip_prefix("//") else {
        return rooted_path(decode(rest)?, uri, syntax);
    };
    let slash = authority_and_path.find('/').unwrap_or(authority_and_path.len());
    let (host, path) = authority_and_path.split_at(slash);
    if host.is_empty() || host.eq_ignore_ascii_case("localhost") {
        return rooted_path(decode(path)?, uri, syntax);
    }
    if syntax == PathSyntax::Unix {
        return Err(UriError::RemoteHost { uri: uri.to_string(), host: host.to_string() });
    }
    // `file://C:/dir`: the drive written where the host belongs.
    let host = decode(host)?;
    if is_drive(&host) {
        let mut drive_path = b"/".to_vec();
        drive_path.extend(host);
        drive_path.extend(decode(path)?);
        return rooted_path(drive_path, uri, syntax);
    }
    if path.len() <= 1 {
        return Err(UriError::RemoteHost { uri: uri.to_string(), host: String::from_utf8_lossy(&host).into() });
    }
    let mut unc = b"//".to_vec();
    unc.extend(host);
    unc.extend(decode(path)?);
    rooted_path(unc, uri, syntax)
}

/// `path`, decoded and starting with `/`, in `syntax`: on Windows `/C:/d`
/// becomes `C:\d` and `//server/share` becomes `\\server\share`.
fn rooted_path(path: Vec<u8>, uri: &str, syntax: PathSyntax) -> Result<Vec<u8>, UriError> {
    if path.first() != Some(&b'/') {
        return Err(UriError::Relative(uri.to_string()));
    }
    if syntax == PathSyntax::Unix {
        return Ok(path);
    }
    let mut windows = if path.len() >= 3 && is_drive(&path[1..3]) {
        let mut drive = vec![path[1], b':'];
        drive.extend(&path[3..]);
        drive
    } else if path.starts_with(b"//") && path.len() > 2 {
        path
    } else {
        // `file:///dir` has no drive: on Windows that is not an absolute path.
        return Err(UriError::Relative(uri.to_string()));
    };
    for byte in &mut windows {
        if *byte == b'/' {
            *byte = b'\\';
        }
    }
    Ok(windows)
}

/// `C:` or `C|` (the RFC 1738 spelling of a drive in a URL).
fn is_drive(text: &[u8]) -> bool {
    matches!(text, [letter, b':' | b'|'] if letter.is_ascii_alphabetic())
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

    fn unix(uri: &str) -> String {
        let bytes = local_path(uri, PathSyntax::Unix).unwrap_or_else(|e| panic!("{uri}: {e}"));
        String::from_utf8(bytes).unwrap()
    }

    fn windows(uri: &str) -> String {
        let bytes = local_path(uri, PathSyntax::Windows).unwrap_or_else(|e| panic!("{uri}: {e}"));
        String::from_utf8(bytes).unwrap()
    }

    #[test]
    fn accepts_the_usual_forms() {
        assert_eq!(unix("file:///tmp/fmu/resources/"), "/tmp/fmu/resources/");
        assert_eq!(unix("file:///tmp/fmu/resources"), "/tmp/fmu/resources");
        assert_eq!(unix("file:/tmp/fmu/resources"), "/tmp/fmu/resources");
        assert_eq!(unix("file://localhost/tmp/r/"), "/tmp/r/");
        assert_eq!(unix("FILE:///tmp/r"), "/tmp/r");
    }

    #[test]
    fn decodes_percent_escapes() {
        assert_eq!(unix("file:///tmp/my%20fmu/res%C3%A9/"), "/tmp/my fmu/resé/");
        assert_eq!(unix("file:///tmp/100%25"), "/tmp/100%");
    }

    #[test]
    fn the_host_platform_gives_its_own_paths() {
        let expected = if cfg!(windows) { r"C:\fmu\resources\" } else { "/C:/fmu/resources/" };
        assert_eq!(resource_directory("file:///C:/fmu/resources/"), Ok(PathBuf::from(expected)));
    }

    #[test]
    fn windows_drives_in_every_spelling() {
        assert_eq!(windows("file:///C:/Users/me/fmu/resources/"), r"C:\Users\me\fmu\resources\");
        assert_eq!(windows("file:/C:/fmu/resources"), r"C:\fmu\resources");
        assert_eq!(windows("file://C:/fmu/resources"), r"C:\fmu\resources");
        assert_eq!(windows("file://localhost/D:/r/"), r"D:\r\");
        assert_eq!(windows("file:///c|/fmu/r"), r"c:\fmu\r");
        assert_eq!(windows("file:///C%3A/fmu/r"), r"C:\fmu\r");
        assert_eq!(windows("file:///C:/Program%20Files/%C3%A9t%C3%A9/r/"), r"C:\Program Files\été\r\");
    }

    #[test]
    fn windows_shares_are_unc_paths() {
        assert_eq!(windows("file://server/share/fmu/resources/"), r"\\server\share\fmu\resources\");
        assert_eq!(windows("file:////server/share/fmu/resources"), r"\\server\share\fmu\resources");
        assert_eq!(windows("file://my%20server/share/r"), r"\\my server\share\r");
    }

    #[test]
    fn rejects_what_is_not_a_local_file() {
        let refusal = |uri| local_path(uri, PathSyntax::Unix);
        assert!(matches!(refusal("http://x/y"), Err(UriError::NotFile(_))));
        assert!(matches!(refusal("/tmp/r"), Err(UriError::NotFile(_))));
        assert!(matches!(refusal(""), Err(UriError::NotFile(_))));
        assert!(matches!(refusal("file://server/share"), Err(UriError::RemoteHost { .. })));
        assert!(matches!(refusal("file:relative/dir"), Err(UriError::Relative(_))));
        assert!(matches!(refusal("file:///tmp/%2"), Err(UriError::BadEscape(_))));
        assert!(matches!(refusal("file:///tmp/%zz"), Err(UriError::BadEscape(_))));
    }

    #[test]
    fn windows_rejects_paths_without_drive_or_share() {
        let refusal = |uri| local_path(uri, PathSyntax::Windows);
        assert!(matches!(refusal("file:///fmu/resources"), Err(UriError::Relative(_))));
        assert!(matches!(refusal("file:C:/fmu"), Err(UriError::Relative(_))));
        assert!(matches!(refusal("file://server"), Err(UriError::RemoteHost { .. })));
        assert!(matches!(refusal("file:///C:/%4"), Err(UriError::BadEscape(_))));
        assert!(matches!(refusal("https://server/share"), Err(UriError::NotFile(_))));
    }
}
