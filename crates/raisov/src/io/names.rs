//! The one rule for names that become file or folder names: a scenario's `name` (its
//! `NAME.pvd`, `frames/NAME_NNNNNN.vtu`, `raisov-out/NAME/`), `raisov mesh levels --name`
//! (`NAME_L0.msh`, ...).
//!
//! A valid name has 1 to [`MAX_NAME_LEN`] characters, each an ASCII letter, a digit, `-`, `_`
//! or `.`, and does not start with `.` ([`NAME_RULE`]). So it has no `/` or `\` (it cannot
//! reach outside the directory it is written in), is neither `.` nor `..` nor hidden, has no
//! control character (no newline in a file name), and leaves room for the suffixes raisov
//! adds (`_surface_000000.vtp`, and the temporary names of [`super::write_atomic`]) within the
//! 255 bytes file systems allow. [`check_name`] checks a name given by the user;
//! [`name_from_stem`] makes a valid default out of a file's stem.

/// The most characters a name may have.
pub const MAX_NAME_LEN: usize = 100;

/// The rule of [`check_name`], in words.
pub const NAME_RULE: &str = "a name has 1 to 100 characters, each an ASCII letter, a digit, \
                             `-`, `_` or `.`, and does not start with `.`";

/// Whether `c` may appear in a name.
fn allowed(c: char) -> bool {
    c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.')
}

/// Check `name` against [`NAME_RULE`]. The error says what is wrong with it and states the
/// rule; the caller adds where the name comes from (the key, the argument).
pub fn check_name(name: &str) -> Result<(), String> {
    let shown = shown(name);
    let problem = if name.is_empty() {
        "is empty".to_string()
    } else if name.chars().count() > MAX_NAME_LEN {
        format!("has {} characters", name.chars().count())
    } else if let Some(c) = name.chars().find(|&c| !allowed(c)) {
        format!("contains {}", describe(c))
    } else if name.starts_with('.') {
        "starts with `.`".to_string()
    } else {
        return Ok(());
    };
    Err(format!("{shown} {problem}; {NAME_RULE}"))
}

/// A valid name made from a file's stem (a default name): every character outside the rule
/// becomes `_`, a leading `.` too, and the result is cut to [`MAX_NAME_LEN`] characters;
/// `fallback` where nothing is left.
pub fn name_from_stem(stem: &str, fallback: &str) -> String {
    let mut s: String = stem
        .chars()
        .take(MAX_NAME_LEN)
        .map(|c| if allowed(c) { c } else { '_' })
        .collect();
    if s.starts_with('.') {
        s.replace_range(0..1, "_");
    }
    if s.is_empty() {
        fallback.to_string()
    } else {
        s
    }
}

/// The name as the message shows it: quoted with escapes, long ones cut.
fn shown(name: &str) -> String {
    const SHOW: usize = 40;
    if name.chars().count() > SHOW {
        let head: String = name.chars().take(SHOW).collect();
        format!("{head:?}...")
    } else {
        format!("{name:?}")
    }
}

/// A character outside the rule, in words.
fn describe(c: char) -> String {
    match c {
        '/' | '\\' => format!("`{c}` (a path separator)"),
        ' ' => "a space".to_string(),
        c if c.is_control() => format!("the control character {c:?}"),
        c => format!("`{c}`"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Names that would leave the directory, hide, clash with `.`/`..`, hold a newline or
    /// overflow a file name are refused, each with the rule stated.
    #[test]
    fn names_outside_the_rule_are_refused_with_the_rule() {
        let long = "a".repeat(300);
        let cases = [
            ("../x", "contains `/` (a path separator)"),
            ("a/b", "contains `/`"),
            ("a\\b", "contains `\\`"),
            ("", "is empty"),
            (".", "starts with `.`"),
            ("..", "starts with `.`"),
            (".hidden", "starts with `.`"),
            ("a\nb", "the control character '\\n'"),
            ("a b", "a space"),
            ("leber-ü", "`ü`"),
            (long.as_str(), "has 300 characters"),
        ];
        for (name, want) in cases {
            let e = check_name(name).unwrap_err();
            assert!(e.contains(want), "{name:?}: {e}");
            assert!(e.ends_with(NAME_RULE), "{name:?}: {e}");
        }
        assert!(check_name(&long).unwrap_err().len() < 300);
        for ok in [
            "drape-2.v1",
            "a",
            "liver_L0",
            "x..y",
            &"b".repeat(MAX_NAME_LEN),
        ] {
            check_name(ok).unwrap();
        }
    }

    #[test]
    fn a_stem_becomes_a_valid_name() {
        for (stem, want) in [
            ("my liver", "my_liver"),
            (".hidden", "_hidden"),
            ("a/b", "a_b"),
            ("", "scenario"),
            ("drape-2.v1", "drape-2.v1"),
        ] {
            let n = name_from_stem(stem, "scenario");
            assert_eq!(n, want);
            check_name(&n).unwrap();
        }
        check_name(&name_from_stem(&"x".repeat(300), "s")).unwrap();
    }
}
