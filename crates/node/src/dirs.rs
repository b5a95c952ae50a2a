//! Where a node keeps things on the machine, after the XDG base directory convention.

use std::path::PathBuf;

/// The base directory `$<var>` when it is set to an absolute path, else `~/<under_home>`; `None`
/// when neither is known.
pub fn xdg(var: &str, under_home: &str) -> Option<PathBuf> {
    std::env::var_os(var)
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(under_home)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_relative_xdg_variable_is_ignored_as_the_convention_says() {
        // Only the shape is checked: the process environment belongs to every test.
        let p = xdg("CETRATUS_NO_SUCH_VARIABLE", ".local/state");
        assert!(p.is_none_or(|p| p.ends_with(".local/state")));
    }
}
