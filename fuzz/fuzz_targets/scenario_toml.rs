//! Any text: `Scenario::from_toml` returns Ok or a typed error, never panics;
//! an accepted scenario can be compiled and simulated for a step.
#![no_main]
use etp_shared::episode::{CompiledScenario, LegMode};
use etp_shared::etkf::Threshold;
use etp_shared::rng::stream_rng;
use etp_shared::scenario::Scenario;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(s) = Scenario::from_toml(text) {
        etp_shared::with_dim!(s.dim, N => {
            let mut c = CompiledScenario::<N>::new(&s);
            c.k_max = c.k_max.min(5);
            let mut rng = stream_rng(0, 0, 0);
            let mut st = c.initial_state(&mut rng);
            let _ = c.run_leg(0, &mut st, &LegMode::EventTriggered(Threshold::new(s.deltas[0])), &mut rng, &mut c.channels(0, 0, 0), &mut ());
        });
    }
});
