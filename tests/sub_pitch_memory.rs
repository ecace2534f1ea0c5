//! The coset engine's memory estimate holds: what `solve_shifted` allocates beyond the
//! set it is given — counted by this test binary's allocator, at its peak — stays within
//! the bytes the engine estimates before it allocates, and a limit one byte below the
//! estimate is refused up front.
//!
//! One test in this binary, so that no other test's allocations are counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::sub_pitch::solve_shifted;
use polycal::solve::{Engine, SolveError, SolveOptions};

/// The system allocator, counting the bytes live now and their peak.
struct Counting;

static LIVE_BYTES: AtomicUsize = AtomicUsize::new(0);
static PEAK_BYTES: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let live = LIVE_BYTES.fetch_add(bytes, Ordering::SeqCst) + bytes;
    PEAK_BYTES.fetch_max(live, Ordering::SeqCst);
}

// SAFETY: every call is passed on to the system allocator unchanged; the counters only
// observe the sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc`, passed on.
        let pointer = unsafe { System.alloc(layout) };
        if !pointer.is_null() {
            grew(layout.size());
        }
        pointer
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc_zeroed`, passed on.
        let pointer = unsafe { System.alloc_zeroed(layout) };
        if !pointer.is_null() {
            grew(layout.size());
        }
        pointer
    }

    unsafe fn dealloc(&self, pointer: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract for `dealloc`, passed on.
        unsafe { System.dealloc(pointer, layout) };
        LIVE_BYTES.fetch_sub(layout.size(), Ordering::SeqCst);
    }

    unsafe fn realloc(&self, pointer: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract for `realloc`, passed on.
        let moved = unsafe { System.realloc(pointer, layout, new_size) };
        if !moved.is_null() {
            // counted as the new block allocated before the old one is freed: the peak
            // a moving realloc reaches
            grew(new_size);
            LIVE_BYTES.fetch_sub(layout.size(), Ordering::SeqCst);
        }
        moved
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The peak of live bytes while `f` runs, above those live when it starts (what it
/// returns is still live at the end, so it is counted).
fn peak_while<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let before = LIVE_BYTES.load(Ordering::SeqCst);
    PEAK_BYTES.store(before, Ordering::SeqCst);
    let value = f();
    (value, PEAK_BYTES.load(Ordering::SeqCst) - before)
}

#[test]
fn the_coset_engines_estimate_bounds_what_it_allocates() {
    let designs = [
        // the designs: 1440 positions, mountings at 0° and 0.1°, 2 cycles,
        // closing; 5760 positions, four mountings
        (1440, 2, vec![0.0, 0.1], true, 0),
        (5760, 4, vec![0.0, 0.0125, 0.03, 0.05], true, 0),
        // missing readings: a larger low-rank part
        (720, 3, vec![0.0, 0.2, 30.25], true, 97),
        (97, 5, vec![0.0, 1.0, 2.5, 3.0, 7.42], false, 29),
    ];
    for (faces, setups, shifts, closing, missing_every) in designs {
        let config = SimulationConfig {
            faces,
            setups,
            table_shift_deg: shifts,
            cycles: 2,
            closing,
            ..SimulationConfig::default()
        };
        let (mut set, _) = simulate(&config).unwrap();
        if missing_every > 0 {
            let mut i = 0;
            set.readings.retain(|_| {
                i += 1;
                i % missing_every != 0
            });
        }
        let estimate = match solve_shifted(&set, &SolveOptions::new().with_memory_limit(1)) {
            Err(SolveError::TooLarge {
                engine,
                needed_bytes,
                ..
            }) => {
                assert_eq!(engine, "coset-circulant");
                needed_bytes
            }
            other => panic!("N = {faces}: {:?}", other.map(|s| s.solution.engine)),
        };
        let limit = u64::try_from(estimate).unwrap();
        // one byte below the estimate: refused before anything is solved
        assert!(matches!(
            solve_shifted(&set, &SolveOptions::new().with_memory_limit(limit - 1)),
            Err(SolveError::TooLarge { .. })
        ));
        let (solved, peak) =
            peak_while(|| solve_shifted(&set, &SolveOptions::new().with_memory_limit(limit)));
        let solved = solved.unwrap();
        assert!(
            matches!(solved.solution.engine, Engine::CosetCirculant { .. }),
            "{:?}",
            solved.solution.engine
        );
        eprintln!(
            "N = {faces}, {setups} mountings, {} readings, rank {:?}: estimate {estimate} \
             bytes, peak {peak} bytes ({:.2})",
            set.readings.len(),
            solved.solution.cofactor.low_rank(),
            estimate as f64 / peak as f64
        );
        assert!(
            peak as u128 <= estimate,
            "N = {faces}: {peak} bytes allocated, {estimate} estimated"
        );
        // and the estimate is of the right size, not a blanket bound
        assert!(
            estimate <= 4 * peak as u128,
            "N = {faces}: {estimate} bytes estimated for {peak}"
        );
    }
}
