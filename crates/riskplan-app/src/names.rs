//! "Did you mean …?" for names a user types (scene names, scene files): the closest of
//! the known names, by case-insensitive equality first, then by edit distance.

/// The largest edit distance (Levenshtein, on lower-cased names) at which a known name is
/// suggested: two slips (a swapped pair, a missing and a wrong letter) still find it; more
/// would suggest unrelated names among short ones.
pub const MAX_SUGGESTION_DISTANCE: usize = 2;

/// How many of the known names a hint lists.
pub const MAX_LISTED_NAMES: usize = 12;

/// The known name closest to `name`: one equal to it but for case, else the nearest within
/// [`MAX_SUGGESTION_DISTANCE`] (the first of equals); `None` when none is close or `name`
/// itself is known.
pub fn closest<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let lower = name.to_lowercase();
    let mut best: Option<(usize, &str)> = None;
    for k in known {
        if k == name {
            return None;
        }
        let d = if k.to_lowercase() == lower { 0 } else { strsim::levenshtein(&k.to_lowercase(), &lower) };
        if d <= MAX_SUGGESTION_DISTANCE && best.is_none_or(|(b, _)| d < b) {
            best = Some((d, k));
        }
    }
    best.map(|(_, k)| k)
}

/// The hint after "unknown scene 'name'": the closest known name, and the known names
/// (at most [`MAX_LISTED_NAMES`], sorted), or that there are none.
pub fn scene_hint<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    let mut names: Vec<&str> = known.into_iter().collect();
    names.sort_unstable();
    if names.is_empty() {
        return ": no scene is loaded (send one with `riskplan client apply --scene NAME --file F`, or start the \
                server with --preload DIR)"
            .into();
    }
    let listed = names.iter().take(MAX_LISTED_NAMES).copied().collect::<Vec<_>>().join(", ");
    let more = names.len().saturating_sub(MAX_LISTED_NAMES);
    let more = if more > 0 { format!(" and {more} more") } else { String::new() };
    match closest(name, names.iter().copied()) {
        Some(c) => format!(": did you mean '{c}'? (loaded: {listed}{more})"),
        None => format!(" (loaded: {listed}{more})"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggests_by_case_then_by_distance() {
        let known = ["illustrative-3", "illustrative-4", "example-d1-cluttered-2d"];
        assert_eq!(closest("Illustrative-3", known), Some("illustrative-3"));
        assert_eq!(closest("ilustrative-3", known), Some("illustrative-3"));
        assert_eq!(closest("illustrative-5", known), Some("illustrative-3"));
        assert_eq!(closest("corridor", known), None);
        assert_eq!(closest("illustrative-3", known), None);
        assert_eq!(closest("x", []), None);
    }

    #[test]
    fn hints_list_the_loaded_names() {
        let h = scene_hint("Illustrative-3", ["illustrative-4", "illustrative-3"]);
        assert_eq!(h, ": did you mean 'illustrative-3'? (loaded: illustrative-3, illustrative-4)");
        assert_eq!(scene_hint("zzz", ["a"]), " (loaded: a)");
        assert!(scene_hint("a", []).contains("no scene is loaded"));
        let many: Vec<String> = (0..20).map(|i| format!("s{i:02}")).collect();
        assert!(scene_hint("q", many.iter().map(String::as_str)).ends_with("and 8 more)"));
    }
}
