//! Memory limits: big allocations (arrays, frame buffers, geometry commits) are checked against
//! the memory the system has available before they are attempted, so that a request the machine
//! cannot hold is reported as ANARI_STATUS_OUT_OF_MEMORY instead of ending in an abort or in the
//! kernel's OOM killer (Linux overcommits: a reservation can succeed and the zero-filling after
//! it kill the process).

/// Requests below this size are not checked: reading /proc/meminfo costs more than they risk.
const CHECKED_FROM: u64 = 64 << 20;

/// A planned allocation the system cannot hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TooBig {
    pub needed: u64,
    pub available: u64,
}

impl std::fmt::Display for TooBig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "need {}, but only {} of memory is available",
            size_text(self.needed),
            size_text(self.available)
        )
    }
}

/// "1.5 GiB", "12.0 MiB", "512 bytes".
pub fn size_text(bytes: u64) -> String {
    const MIB: f64 = (1u64 << 20) as f64;
    const GIB: f64 = (1u64 << 30) as f64;
    let b = bytes as f64;
    if b >= GIB {
        format!("{:.1} GiB", b / GIB)
    } else if b >= MIB {
        format!("{:.1} MiB", b / MIB)
    } else {
        format!("{bytes} bytes")
    }
}

/// Memory the system can still hand out without swapping: `MemAvailable` of /proc/meminfo.
/// `None` where that is unknown (then only the allocator's own failure is caught).
pub fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_available(&text)
}

fn parse_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let mut words = line.split_whitespace().skip(1);
    let value: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => value.checked_mul(1024),
        None => Some(value),
        Some(_) => None,
    }
}

/// Whether `needed` bytes fit in `available` (None: unknown, so allowed).
fn fits(needed: u64, available: Option<u64>) -> Result<(), TooBig> {
    match available {
        Some(available) if needed >= CHECKED_FROM && needed > available => {
            Err(TooBig { needed, available })
        }
        _ => Ok(()),
    }
}

/// Checks a planned allocation of `needed` bytes against the memory available now.
pub fn check(needed: u64) -> Result<(), TooBig> {
    if needed < CHECKED_FROM {
        return Ok(());
    }
    fits(needed, available_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_available_is_read_in_bytes() {
        let meminfo = "MemTotal:       24684092 kB\nMemFree:        23514924 kB\n\
                       MemAvailable:   24044248 kB\nBuffers:           12836 kB\n";
        assert_eq!(parse_available(meminfo), Some(24044248 * 1024));
        assert_eq!(parse_available("MemTotal: 5 kB\n"), None);
        assert_eq!(parse_available("MemAvailable: lots kB\n"), None);
    }

    #[test]
    fn big_requests_beyond_what_is_available_are_refused() {
        let gib = 1u64 << 30;
        assert_eq!(
            fits(5 * gib, Some(4 * gib)),
            Err(TooBig {
                needed: 5 * gib,
                available: 4 * gib
            })
        );
        assert_eq!(fits(3 * gib, Some(4 * gib)), Ok(()));
        // Small requests are left to the allocator; unknown availability allows everything.
        assert_eq!(fits(1 << 20, Some(0)), Ok(()));
        assert_eq!(fits(u64::MAX, None), Ok(()));
        let text = TooBig {
            needed: 5 * gib,
            available: 3 * gib / 2,
        }
        .to_string();
        assert_eq!(
            text,
            "need 5.0 GiB, but only 1.5 GiB of memory is available"
        );
    }

    #[test]
    fn this_machine_reports_its_available_memory() {
        if cfg!(target_os = "linux") {
            assert!(available_bytes().is_some_and(|b| b > 0));
        }
    }
}
