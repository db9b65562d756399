//! What the machine has room for, read before a run: the memory available to a new
//! allocation and the free disk under a folder (for [`super::budget`]'s checks).

use std::path::Path;

/// The memory the kernel says can be allocated without swapping (`MemAvailable` in
/// `/proc/meminfo`), bytes; infinite where it cannot be read (no limit is then imposed).
#[must_use]
pub fn available_memory_bytes() -> f64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find_map(|line| line.strip_prefix("MemAvailable:"))
                .and_then(|rest| rest.trim().strip_suffix("kB"))
                .and_then(|kb| kb.trim().parse::<f64>().ok())
        })
        .map_or(f64::INFINITY, |kb| kb * 1024.0)
}

/// The free bytes an unprivileged writer has on the disk holding `folder`, or its nearest
/// existing parent (the output folder may not exist yet); infinite where none can be read.
#[must_use]
pub fn free_disk_bytes(folder: &Path) -> f64 {
    let absolute = std::path::absolute(folder).unwrap_or_else(|_| folder.to_owned());
    absolute
        .ancestors()
        .find_map(|dir| nix::sys::statvfs::statvfs(dir).ok())
        .map_or(f64::INFINITY, |stat| {
            stat.blocks_available() as f64 * stat.fragment_size() as f64
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_machine_has_some_memory_and_disk_and_a_missing_folder_uses_its_parent() {
        let memory = available_memory_bytes();
        assert!(memory > 1e6 && memory.is_finite(), "{memory}");
        let dir = tempfile::tempdir().expect("a temporary folder");
        let here = free_disk_bytes(dir.path());
        let below = free_disk_bytes(&dir.path().join("not/yet/made"));
        assert!(here > 0.0 && here.is_finite(), "{here}");
        // The same disk, read a moment apart: within what another writer could take.
        assert!((here - below).abs() < 1e9, "{here} vs {below}");
    }
}
