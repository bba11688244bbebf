//! Checks on `.osim` text written back with personalized joint frames.

/// The lines (0-based) where `new` differs from `old`, after checking that the two have the
/// same number of lines and that each changed line is a `<translation>` or `<orientation>`
/// inside one of the named joints (the nearest `Joint name="…"` line above it).
///
/// # Panics
/// When a line count differs or a changed line is not an offset of a named joint.
pub fn changed_offset_lines(old: &str, new: &str, joints: &[&str]) -> Vec<usize> {
    let old: Vec<&str> = old.lines().collect();
    let new: Vec<&str> = new.lines().collect();
    assert_eq!(old.len(), new.len(), "line count");
    let changed: Vec<usize> = (0..old.len()).filter(|&i| old[i] != new[i]).collect();
    for &i in &changed {
        assert!(
            new[i].contains("<translation>") || new[i].contains("<orientation>"),
            "line {}: {} -> {}",
            i + 1,
            old[i].trim(),
            new[i].trim()
        );
        let owner = old[..i]
            .iter()
            .rev()
            .find(|l| l.contains("Joint name="))
            .unwrap_or_else(|| panic!("line {} changed outside a joint", i + 1));
        assert!(
            joints.iter().any(|j| owner.contains(&format!("\"{j}\""))),
            "line {} changed inside {owner}",
            i + 1
        );
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::changed_offset_lines;

    const OLD: &str = "<A>\n<Joint name=\"hip\">\n<translation>0 0 0</translation>\n\
                       <Joint name=\"knee\">\n<orientation>0 0 0</orientation>\n</A>";

    #[test]
    fn offsets_of_named_joints_may_change() {
        let new = OLD.replace("<translation>0 0 0", "<translation>1 0 0");
        assert_eq!(changed_offset_lines(OLD, &new, &["hip"]), [2]);
        assert!(changed_offset_lines(OLD, OLD, &["hip"]).is_empty());
    }

    #[test]
    #[should_panic(expected = "changed inside")]
    fn an_offset_of_another_joint_may_not() {
        let new = OLD.replace("<orientation>0 0 0", "<orientation>0 1 0");
        changed_offset_lines(OLD, &new, &["hip"]);
    }

    #[test]
    #[should_panic(expected = "line 1")]
    fn other_lines_may_not() {
        changed_offset_lines(OLD, &OLD.replace("<A>", "<B>"), &["hip"]);
    }
}
