//! The default job memory budget, from what the process may really use (the machine's
//! memory, its cgroup's `memory.max`, its inherited address-space limit), and the check
//! of a budget the operator asks for against those limits.

/// The default memory budget per job: what the process may really use (the machine's
/// memory, its cgroup's `memory.max`, its inherited address-space limit), see
/// `default_budget_mb`.
pub fn default_job_memory_mb(workers: usize) -> u64 {
    default_budget_mb(
        total_memory_bytes(),
        cgroup_memory_max(),
        crate::isolate::inherited_address_space().map(crate::isolate::budget_under_address_space),
        workers,
    )
}

/// The default budget, MiB: the smaller of the machine's memory and the cgroup's limit
/// (both shared by every job at once) divided by the workers, at most 16 GiB and at least
/// 512 MiB; then never above `address_space_fit_mb`, the budget a job process can be given
/// under an inherited RLIMIT_AS (per process, so not divided: each job gets its own).
pub fn default_budget_mb(
    total_bytes: Option<u64>,
    cgroup_bytes: Option<u64>,
    address_space_fit_mb: Option<u64>,
    workers: usize,
) -> u64 {
    let total_mb = total_bytes.map(|b| b >> 20).unwrap_or(4096);
    let shared_mb = cgroup_bytes.map_or(total_mb, |c| total_mb.min(c >> 20));
    let budget = (shared_mb / workers.max(1) as u64).clamp(512, 16 << 10);
    match address_space_fit_mb {
        // Above it every job process would fail to start (setrlimit EPERM).
        Some(fit) => budget.min(fit),
        None => budget,
    }
}

/// Refuses an explicit `--job-memory-mb` no job process could be given: above what the
/// inherited address-space limit leaves a job (`address_space_fit_mb`, with the limit
/// `address_space_bytes`), or above the cgroup's `memory.max` (one job alone would be
/// killed by the kernel before reaching it).
pub fn check_requested_budget(
    requested_mb: u64,
    address_space: Option<(u64, u64)>,
    cgroup_bytes: Option<u64>,
) -> Result<(), String> {
    if let Some((limit_bytes, fit_mb)) = address_space {
        if requested_mb > fit_mb {
            return Err(format!(
                "--job-memory-mb {requested_mb} is above the {fit_mb} MiB the inherited address-space limit (ulimit -v, LimitAS=: {} MiB, less what a job process needs besides its budget) allows; lower --job-memory-mb or raise the limit",
                limit_bytes >> 20
            ));
        }
    }
    if let Some(c) = cgroup_bytes {
        if requested_mb > c >> 20 {
            return Err(format!(
                "--job-memory-mb {requested_mb} is above the {} MiB the cgroup's memory.max (the container's memory limit) allows; lower --job-memory-mb or raise the limit",
                c >> 20
            ));
        }
    }
    Ok(())
}

/// The memory limit of this process's cgroup (v2) and its ancestors, the smallest, bytes;
/// None when there is none (or no cgroup v2).
pub fn cgroup_memory_max() -> Option<u64> {
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = cgroup_v2_path(&own)?;
    let root = std::path::Path::new("/sys/fs/cgroup");
    // A parent's limit holds for its children too: walk up to the root.
    let mut dir = root.join(path.trim_start_matches('/'));
    let mut smallest: Option<u64> = None;
    loop {
        if let Ok(text) = std::fs::read_to_string(dir.join("memory.max")) {
            if let Some(b) = parse_memory_max(&text) {
                smallest = Some(smallest.map_or(b, |s| s.min(b)));
            }
        }
        if dir == root || !dir.pop() || !dir.starts_with(root) {
            break;
        }
    }
    smallest
}

/// The cgroup v2 path in `/proc/self/cgroup` contents (the `0::/path` line).
pub fn cgroup_v2_path(proc_self_cgroup: &str) -> Option<&str> {
    proc_self_cgroup
        .lines()
        .find_map(|l| l.strip_prefix("0::"))
        .map(str::trim)
        .filter(|p| p.starts_with('/'))
}

/// A `memory.max` file's contents: bytes, or None for `max` (no limit) or unreadable text.
pub fn parse_memory_max(text: &str) -> Option<u64> {
    match text.trim() {
        "max" => None,
        n => n.parse().ok(),
    }
}

/// Total memory of the machine (MemTotal of /proc/meminfo), if known.
fn total_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_budget_shares_the_memory_within_bounds() {
        let one = default_job_memory_mb(1);
        assert!((512..=16 << 10).contains(&one));
        assert!(default_job_memory_mb(10_000) == 512);
    }

    #[test]
    fn the_cgroup_limit_is_read_from_its_files() {
        let v1_and_v2 = "4:memory:/process_api/8a27\n1:cpu:/\n0::/system.slice/millsim.service\n";
        assert_eq!(
            cgroup_v2_path(v1_and_v2),
            Some("/system.slice/millsim.service")
        );
        assert_eq!(cgroup_v2_path("0::/\n"), Some("/"));
        // cgroup v1 only: no v2 path, so no limit read.
        assert_eq!(cgroup_v2_path("4:memory:/docker/abc\n1:cpu:/\n"), None);
        assert_eq!(parse_memory_max("max\n"), None);
        assert_eq!(parse_memory_max("4294967296\n"), Some(4 << 30));
        assert_eq!(parse_memory_max(""), None);
    }

    #[test]
    fn the_default_budget_is_the_smallest_limit_shared_by_the_workers() {
        let gib = 1u64 << 30;
        // Machine 64 GiB, 4 workers: 16 GiB each.
        assert_eq!(default_budget_mb(Some(64 * gib), None, None, 4), 16 << 10);
        // A container limited to 8 GiB on that machine: 2 GiB each.
        assert_eq!(
            default_budget_mb(Some(64 * gib), Some(8 * gib), None, 4),
            2048
        );
        // A cgroup limit above the machine's memory changes nothing.
        assert_eq!(
            default_budget_mb(Some(8 * gib), Some(64 * gib), None, 2),
            4096
        );
        // An inherited address-space limit caps each job, not divided (each process has its own).
        assert_eq!(default_budget_mb(Some(64 * gib), None, Some(5000), 2), 5000);
        assert_eq!(
            default_budget_mb(Some(64 * gib), Some(8 * gib), Some(5000), 2),
            4096
        );
        // Under a tiny address-space limit, below the usual 512 MiB floor.
        assert_eq!(default_budget_mb(Some(64 * gib), None, Some(100), 1), 100);
    }

    #[test]
    fn a_requested_budget_above_a_limit_is_refused_naming_both() {
        let as_limit = Some((6u64 << 30, 4864));
        let e = check_requested_budget(12000, as_limit, None).unwrap_err();
        assert!(
            e.contains("--job-memory-mb 12000")
                && e.contains("4864 MiB")
                && e.contains("address-space"),
            "{e}"
        );
        assert!(check_requested_budget(4864, as_limit, None).is_ok());
        let e = check_requested_budget(3000, None, Some(2 << 30)).unwrap_err();
        assert!(
            e.contains("--job-memory-mb 3000")
                && e.contains("2048 MiB")
                && e.contains("memory.max"),
            "{e}"
        );
        assert!(check_requested_budget(2048, None, Some(2 << 30)).is_ok());
        assert!(check_requested_budget(1 << 20, None, None).is_ok());
    }
}
