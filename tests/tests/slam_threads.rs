//! The pipeline's result does not depend on the number of threads: scans,
//! images and sequential matches are built in parallel, and loop
//! candidates are matched in parallel (in the mission pass, the retries
//! and the densification pass), but every result is collected and judged
//! in the candidates' order.

use echofield::slam::{NoProgress, SlamConfig, SlamOutput, run_mission};
use echofield_datasets::sim::{Scenario, simulate_mission};

fn run_on(threads: usize, config: &SlamConfig) -> SlamOutput {
    let mission = simulate_mission(&Scenario::named("tank").unwrap(), 3).unwrap();
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| run_mission(&mission, config, &NoProgress).unwrap())
}

#[test]
fn one_thread_and_four_give_the_same_run() {
    // The tank has about ten rotations: loops between nodes 3 apart.
    let config = SlamConfig::from_toml_str("[loops]\nmin_separation_nodes = 3\n").unwrap();
    let one = run_on(1, &config);
    let four = run_on(4, &config);
    let mission_pass = one.loops.iter().filter(|l| !l.densified).count();
    let densified = one.loops.iter().filter(|l| l.densified).count();
    assert!(
        mission_pass >= 4 && densified >= 4,
        "too few candidates to exercise the parallel matching: {mission_pass} in the mission, {densified} densified"
    );
    assert_eq!(one.loops, four.loops);
    assert_eq!(one.sequential, four.sequential);
    let poses = |o: &SlamOutput| o.nodes.iter().map(|n| n.optimised).collect::<Vec<_>>();
    assert_eq!(poses(&one), poses(&four));
}
