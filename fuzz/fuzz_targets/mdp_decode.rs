//! Any bytes: `Mdp::decode` returns Ok or a typed error, never panics or
//! allocates without bound; an accepted MDP gets a Pareto front.
#![no_main]
use etp_synthesis::mdp::Mdp;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = Mdp::decode(data) {
        let _ = etp_synthesis::pareto::compute_front(&m, Default::default());
    }
});
