//! Any bytes: `Mdp::decode` returns Ok or a typed error, never panics or
//! allocates without bound; an accepted MDP gets a Pareto front. The bytes
//! are tried twice: as a whole file (almost always refused by the SHA-256
//! checksum of format 2) and as the bincode body of a file with a valid
//! header and checksum, so the decoder behind the checksum is fuzzed too.
//! Seeds: `mdp.bin` files of `etp synthesize` (their bytes 12..len-32 are a body).
#![no_main]
use etp_synthesis::mdp::Mdp;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    for file in [data.to_vec(), Mdp::file_of_body(data)] {
        if let Ok(m) = Mdp::decode(&file) {
            let _ = etp_synthesis::pareto::compute_front(&m, Default::default());
        }
    }
});
