//! The one-line error message `main` prints: the chain of causes, each said once. Library errors
//! often show their source in their own text ("file: record 0: truncated file") and report it as
//! their source too; printing the chain as is would repeat the cause two or three times.

/// `s` with its control characters but line breaks and tabs escaped (`\u{1b}`): text from input
/// (a `--describe` sentence, a file's content quoted in an error) never drives the terminal.
pub fn printable(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_control() && c != '\n' && c != '\t' { c.escape_default().to_string() } else { c.to_string() })
        .collect()
}

/// The causes of `e`, outermost first, joined by ": ", leaving out a cause whose text the
/// message already holds.
pub fn message(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        let text = printable(&text);
        if text.is_empty() || out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug)]
    struct Inner;
    impl std::fmt::Display for Inner {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("truncated file")
        }
    }
    impl std::error::Error for Inner {}

    #[derive(Debug)]
    struct Outer(Inner);
    impl std::fmt::Display for Outer {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "a.tfrecord: record 0: {}", self.0)
        }
    }
    impl std::error::Error for Outer {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.0)
        }
    }

    #[test]
    fn control_characters_are_escaped() {
        let e = anyhow::anyhow!("could not read \"brake\u{1b}[2J\u{7}\r now\"");
        assert_eq!(message(&e), "could not read \"brake\\u{1b}[2J\\u{7}\\r now\"");
        assert_eq!(printable("ünïcode ok"), "ünïcode ok");
    }

    #[test]
    fn each_cause_is_said_once() {
        let e = anyhow::Error::new(Outer(Inner)).context("ingest failed; nothing was written");
        assert_eq!(message(&e), "ingest failed; nothing was written: a.tfrecord: record 0: truncated file");
        let plain = anyhow::anyhow!("x").context("y");
        assert_eq!(message(&plain), "y: x");
    }
}
