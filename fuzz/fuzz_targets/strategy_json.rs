//! Any text: `Strategy::from_json` returns Ok or a typed error, never panics;
//! an accepted strategy can be asked for δ at every decision point.
#![no_main]
use etp_shared::strategy::Strategy;
use libfuzzer_sys::fuzz_target;
use nalgebra::DMatrix;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(s) = Strategy::from_json(text) {
        for dp in 0..8 {
            for n in 1..=3 {
                let _ = s.draw(dp, &DMatrix::identity(n, n).scale(1e-3), 0.5);
            }
        }
        let _ = s.scenario();
    }
});
