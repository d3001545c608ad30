//! How many worker threads a command runs: `--threads`, else
//! `RAYON_NUM_THREADS`, else the cores — never more than the cores
//! available to the process (its CPU quota or affinity mask), shared among
//! the processes on the node (MPI ranks).
//!
//! More threads than cores buy nothing here and cost a lot: rayon workers
//! spin and yield while they look for work, and the nested parallel linear
//! algebra of the operator precomputation splits each small factorisation
//! over all of them. A larger request is lowered with a note (for
//! stderr); a `RAYON_NUM_THREADS` that is not a number is an error rather
//! than silently ignored (rayon itself ignores it).

use crate::error::{FileError, Result};

/// Name of the environment variable read for the default thread count.
pub const THREADS_ENV: &str = "RAYON_NUM_THREADS";

/// The thread count chosen, and a note to print when a request was
/// lowered.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Threads {
    /// Threads to run.
    pub count: usize,
    /// Set when the request was more than the cores available: says so.
    pub note: Option<String>,
}

/// The threads for a process: `flag` (`--threads`), else
/// [`THREADS_ENV`], else the cores available to the process divided
/// among the `sharing` processes on its node (at least 1); a request above
/// that share is lowered to it, with a note.
pub fn choose(flag: Option<usize>, sharing: usize) -> Result<Threads> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    decide(
        flag,
        std::env::var(THREADS_ENV).ok().as_deref(),
        cores,
        sharing,
    )
}

/// [`choose`] with the environment variable's value and the core count
/// given.
pub fn decide(
    flag: Option<usize>,
    env: Option<&str>,
    cores: usize,
    sharing: usize,
) -> Result<Threads> {
    let share = (cores / sharing.max(1)).max(1);
    let cores_text = if sharing > 1 {
        format!("the {share} cores available to each of the {sharing} processes on this node")
    } else {
        format!("the {share} available cores")
    };
    let (requested, source) = match (flag, env.map(str::trim)) {
        (Some(0), _) => return Err(FileError::Threads("--threads must be at least 1".into())),
        (Some(t), _) => (t, format!("--threads {t}")),
        // Unset, empty or 0: rayon's own default (one thread per core).
        (None, None | Some("") | Some("0")) => {
            return Ok(Threads {
                count: share,
                note: None,
            });
        }
        (None, Some(text)) => match text.parse::<usize>() {
            Ok(t) => (t, format!("{THREADS_ENV}={t}")),
            Err(_) => {
                return Err(FileError::Threads(format!(
                    "{THREADS_ENV}={text:?} is not a thread count: give a positive integer, \
                     or unset it for one thread per core"
                )));
            }
        },
    };
    if requested > share {
        return Ok(Threads {
            count: share,
            note: Some(format!(
                "note: {source} is more than {cores_text}: using {share} threads"
            )),
        });
    }
    Ok(Threads {
        count: requested,
        note: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_capped_at_the_share_of_the_cores() {
        let t = decide(Some(10_000), None, 8, 1).unwrap();
        assert_eq!(t.count, 8);
        assert!(t.note.unwrap().contains("--threads 10000"));
        let t = decide(None, Some("10000"), 8, 2).unwrap();
        assert_eq!(t.count, 4);
        let note = t.note.unwrap();
        assert!(note.contains("RAYON_NUM_THREADS=10000") && note.contains("2 processes"));
        assert_eq!(decide(Some(3), Some("junk"), 8, 1).unwrap().count, 3);
        assert_eq!(decide(None, None, 8, 3).unwrap().count, 2);
        assert_eq!(decide(None, Some("0"), 8, 16).unwrap().count, 1);
        assert_eq!(
            decide(None, Some(" 2 "), 8, 1).unwrap(),
            Threads {
                count: 2,
                note: None
            }
        );
    }

    #[test]
    fn bad_counts_are_errors() {
        let e = decide(Some(0), None, 8, 1).unwrap_err().to_string();
        assert!(e.contains("at least 1"), "{e}");
        for bad in ["abc", "-1", "1.5", "4x"] {
            let e = decide(None, Some(bad), 8, 1).unwrap_err().to_string();
            assert!(e.contains("RAYON_NUM_THREADS") && e.contains(bad), "{e}");
        }
    }
}
