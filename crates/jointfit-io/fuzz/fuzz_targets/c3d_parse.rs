//! Any byte string: `parse_c3d` returns Ok or Err, never panics, and a parsed file converts to
//! a trial (or a typed error) without panicking.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(c) = jointfit_io::c3d::parse_c3d(data) {
        let _ = c.to_trial();
        let _ = c.parameters.strings_continued("POINT", "LABELS");
    }
});
