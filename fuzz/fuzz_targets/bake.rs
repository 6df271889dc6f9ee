//! Any bytes, read as a bake file: `from_bytes` returns Ok or an Err that says something, and
//! whatever it accepts runs through every run-time consumer (`check_consumers`) without a
//! panic or an error.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match skinlet::bake::from_bytes(data) {
        Ok(baked) => {
            if let Err(e) = skinlet::bake::check_consumers(&baked) {
                panic!("accepted, but a consumer refused it: {e}");
            }
        }
        Err(e) => assert!(!e.to_string().trim().is_empty(), "empty error message"),
    }
});
