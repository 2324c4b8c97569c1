//! Any bytes as a recording: the lenient MCAP reader returns Ok or a typed
//! error, never panics; every message it yields decodes or errors; the
//! estimator re-run of `etp replay --verify` terminates without panicking on
//! whatever the file holds (seed: `recordings/fixtures/*.mcap`).
#![no_main]
use etp_runtime::recording;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(c) = recording::read_lenient("fuzz", data) else {
        return;
    };
    for m in &c.messages {
        let _ = m.decode();
        // Every encoding, whatever the channel says.
        for e in [
            recording::Encoding::Protobuf,
            recording::Encoding::Protobuf5,
            recording::Encoding::Bincode,
        ] {
            let _ = e.decode(&m.topic, &m.data);
        }
    }
    let _ = c.counts();
    let _ = recording::verify(&c);
});
