//! Generation time of the procedural chest phantom (`tomograf_datasets::anatomy`).
//!
//! ```text
//! cargo run --release -p tomograf-datasets --example anatomy_timing
//! ```
//!
//! Prints the median of 3 runs for 128³ (3.5 mm voxels) and 256³ (1.75 mm voxels) grids,
//! both covering 448 mm, for both profiles, with table and pacemaker. `RAYON_NUM_THREADS`
//! sets the number of threads.

use std::time::{Duration, Instant};
use tomograf_datasets::anatomy::{AnatomySpec, Profile, generate};

fn main() {
    println!(
        "anatomy phantom generation, {} threads, median of 3 runs",
        rayon::current_num_threads()
    );
    for profile in [Profile::LidcCropped, Profile::FullChest] {
        for (n, spacing) in [(128usize, 3.5f64), (256, 1.75)] {
            let mut times: Vec<Duration> = (0..3u64)
                .map(|seed| {
                    let mut spec = AnatomySpec::new(seed, profile, [n; 3], [spacing; 3]);
                    spec.table = true;
                    spec.pacemaker = true;
                    let t = Instant::now();
                    let v = generate(&spec).expect("generation failed");
                    let dt = t.elapsed();
                    assert_eq!(v.len(), n * n * n);
                    dt
                })
                .collect();
            times.sort();
            println!(
                "{profile:?} {n}³ ({spacing} mm): {:.3} s (min {:.3} s, max {:.3} s)",
                times[1].as_secs_f64(),
                times[0].as_secs_f64(),
                times[2].as_secs_f64()
            );
        }
    }
}
