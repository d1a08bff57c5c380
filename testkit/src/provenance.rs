//! Where a generated results page came from: the machine and the commit its
//! header names (docs/README.md: every results page says its command,
//! machine and commit). `examples/provenance.py` writes the same header for
//! the Python generators.

use std::process::Command;

/// The kind line a generated results page opens with:
/// `*Results, generated.* Command below; machine: …; commit … (date).`
pub fn header() -> String {
    format!(
        "*Results, generated.* Command below; machine: {}; commit {}.",
        machine(),
        commit()
    )
}

/// CPU model, logical cores and operating system, from /proc/cpuinfo and
/// /etc/os-release where they exist.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let os = std::fs::read_to_string("/etc/os-release")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("PRETTY_NAME="))
                .map(|v| v.trim_matches('"').to_string())
        })
        .unwrap_or_else(|| std::env::consts::OS.to_string());
    format!("{cpu}, {cores} cores, {os}")
}

/// The short hash of HEAD (`+changes` when the work tree differs from it) and
/// today's date, or "unknown" outside a git checkout.
pub fn commit() -> String {
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let hash = git(&["rev-parse", "--short", "HEAD"]).unwrap_or_else(|| "unknown".into());
    let dirty =
        git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    let date = Command::new("date")
        .arg("+%Y-%m-%d")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    format!("{hash}{} ({date})", if dirty { "+changes" } else { "" })
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_header_is_a_results_kind_line_naming_machine_and_commit() {
        let h = super::header();
        assert!(h.starts_with("*Results, generated.*"), "{h}");
        assert!(
            h.contains("machine: ") && h.contains("cores") && h.contains("commit "),
            "{h}"
        );
    }
}
