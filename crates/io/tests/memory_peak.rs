//! The heap a read or a write holds at its peak: reading a `.npy` file
//! takes the final array and a bounded buffer, never a second full-size
//! copy (raw bytes, a converted or transposed array); writing an output
//! takes a bounded buffer, never the whole file in memory.
//!
//! A binary of its own: a counting global allocator measures the heap
//! (current and peak bytes) of everything the read or write allocates.
//! `FERROFMM_IO_PEAK_N` sets the number of points (default 2,000,000).

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use ferrofmm_io::{Contents, Reader, Values, npy};

/// The system allocator, counting live bytes and their high-water mark.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is forwarded unchanged to `System`, which upholds the
// `GlobalAlloc` contract; the counters only observe the sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc` is passed on unchanged.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(live, Ordering::Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc_zeroed` is passed on unchanged.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(live, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `alloc` above with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract for `realloc` is passed on unchanged.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            // While the block moves, old and new are both held.
            let peak = LIVE.load(Ordering::Relaxed) + new_size;
            PEAK.fetch_max(peak, Ordering::Relaxed);
            if new_size >= layout.size() {
                LIVE.fetch_add(new_size - layout.size(), Ordering::Relaxed);
            } else {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Start a measurement: the live bytes now (the peak is reset to them).
fn reset_peak() -> usize {
    let live = LIVE.load(Ordering::Relaxed);
    PEAK.store(live, Ordering::Relaxed);
    live
}

/// The peak since `reset_peak` returned `base`, above `base`.
fn peak_above(base: usize) -> usize {
    PEAK.load(Ordering::Relaxed).saturating_sub(base)
}

const MIB: f64 = 1024.0 * 1024.0;

/// What a read or write may hold besides the array itself: its buffers
/// (the reader's chunk and `BufReader`, the writer's chunk and
/// `BufWriter`) and small things (the header, the path, messages).
const SLACK: usize = 1 << 20;

/// A fresh directory under the system temp dir, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        let dir =
            std::env::temp_dir().join(format!("ferrofmm-io-peak-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn n_points() -> usize {
    std::env::var("FERROFMM_IO_PEAK_N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2_000_000)
}

/// The value at flat index `k` of the test arrays.
fn value(k: usize) -> f64 {
    (k % 1009) as f64 * 1e-3 - 0.5
}

/// An `(n, 3)` little-endian `float64` C-order file of `value(k)`,
/// written in pieces (the test's own memory stays small).
fn write_points(path: &Path, n: usize) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    f.write_all(&npy::header_bytes(n as u64, 3)).unwrap();
    for k in 0..3 * n {
        f.write_all(&value(k).to_le_bytes()).unwrap();
    }
    f.flush().unwrap();
}

/// The same array as a Fortran-order big-endian `float32` file.
fn write_points_fortran_f32(path: &Path, n: usize) {
    let dict = format!("{{'descr': '>f4', 'fortran_order': True, 'shape': ({n}, 3), }}");
    let total = 10 + dict.len() + 1;
    let dict = format!("{dict}{}\n", " ".repeat(total.next_multiple_of(64) - total));
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    f.write_all(b"\x93NUMPY\x01\x00").unwrap();
    f.write_all(&(dict.len() as u16).to_le_bytes()).unwrap();
    f.write_all(dict.as_bytes()).unwrap();
    for j in 0..3 {
        for i in 0..n {
            f.write_all(&(value(3 * i + j) as f32).to_be_bytes())
                .unwrap();
        }
    }
    f.flush().unwrap();
}

/// Reads of `n` points (whole, a row range, Fortran-order `float32`) hold
/// the array read and a bounded buffer; writes of `n` records of four
/// values (`.npy` and `.csv`, real and complex) hold a bounded buffer.
#[test]
fn reads_and_writes_hold_no_second_copy() {
    let n = n_points();
    let dir = Scratch::new("reads");
    let array = 24 * n;

    let c_order = dir.path("p.npy");
    write_points(&c_order, n);
    let base = reset_peak();
    let p = Reader::new().read(&c_order, Contents::Points).unwrap();
    let whole = peak_above(base);
    assert_eq!(p.len(), 3 * n);
    assert!(p.iter().take(3000).enumerate().all(|(k, &v)| v == value(k)));
    eprintln!(
        "read {n} x 3 float64 .npy ({:.1} MiB): peak {:.1} MiB above the start",
        array as f64 / MIB,
        whole as f64 / MIB
    );
    assert!(
        whole <= array + SLACK,
        "reading {} MiB took {} MiB",
        array as f64 / MIB,
        whole as f64 / MIB
    );

    // A rank's share: only its rows.
    let rows = n as u64 / 4..n as u64 / 2;
    let base = reset_peak();
    let (part, total) = Reader::new()
        .read_rows(&c_order, Contents::Points, |_| rows.clone())
        .unwrap();
    let ranged = peak_above(base);
    assert_eq!(total, n as u64);
    assert_eq!(part[0], value(3 * rows.start as usize));
    let part_bytes = 8 * part.len();
    eprintln!(
        "read rows {rows:?}: peak {:.1} MiB for {:.1} MiB of rows",
        ranged as f64 / MIB,
        part_bytes as f64 / MIB
    );
    assert!(
        ranged <= part_bytes + SLACK,
        "{ranged} bytes for {part_bytes}"
    );

    // Fortran order, big-endian float32: the f64 array alone.
    let fortran = dir.path("f.npy");
    write_points_fortran_f32(&fortran, n);
    drop(p);
    let base = reset_peak();
    let p = Reader::new().read(&fortran, Contents::Points).unwrap();
    let transposed = peak_above(base);
    assert_eq!(
        p[..6],
        [0, 1, 2, 3, 4, 5].map(|k| f64::from(value(k) as f32))
    );
    eprintln!(
        "read {n} x 3 Fortran-order >f4 .npy: peak {:.1} MiB above the start",
        transposed as f64 / MIB
    );
    assert!(
        transposed <= array + SLACK,
        "{transposed} bytes for {array}"
    );

    // Raw little-endian float64 (the MPI tree's .f64 input).
    let raw = dir.path("p.f64");
    {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&raw).unwrap());
        for k in 0..3 * n {
            f.write_all(&value(k).to_le_bytes()).unwrap();
        }
        f.flush().unwrap();
    }
    drop(p);
    let base = reset_peak();
    let p = Reader::new().read(&raw, Contents::Points).unwrap();
    let raw_peak = peak_above(base);
    assert_eq!(p[3 * n - 1], value(3 * n - 1));
    eprintln!(
        "read {n} x 3 raw .f64: peak {:.1} MiB above the start",
        raw_peak as f64 / MIB
    );
    assert!(raw_peak <= array + SLACK, "{raw_peak} bytes for {array}");
    drop(p);

    // Writes: potential and gradient of every point.
    let values: Vec<f64> = (0..4 * n).map(value).collect();
    for name in ["o.npy", "o.csv"] {
        let out = dir.path(name);
        let base = reset_peak();
        ferrofmm_io::write(
            &out,
            Values::F64(&values),
            &["potential", "grad_x", "grad_y", "grad_z"],
        )
        .unwrap();
        let written = peak_above(base);
        eprintln!(
            "write {n} x 4 float64 {name}: peak {:.2} MiB",
            written as f64 / MIB
        );
        assert!(written <= SLACK, "writing {name} took {written} bytes");
        let base = reset_peak();
        ferrofmm_io::write_complex(
            &out,
            Values::F64(&values),
            &["potential_re", "potential_im", "grad_x_re", "grad_x_im"],
        )
        .unwrap();
        let written = peak_above(base);
        eprintln!(
            "write {n} x 2 complex128 {name}: peak {:.2} MiB",
            written as f64 / MIB
        );
        assert!(
            written <= SLACK,
            "writing complex {name} took {written} bytes"
        );
    }
}
