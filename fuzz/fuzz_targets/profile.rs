//! The profile parser and validator on arbitrary text: refuse or accept, never panic; an
//! accepted profile gives a working Stewart platform at neutral.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(profile) = hexcue_core::profile::text::parse_profile(text, "fuzz.toml") {
        // What the engine does first with a profile: it must not panic either.
        let stewart = profile.stewart();
        let neutral = nalgebra::Vector6::zeros();
        let legs = stewart.leg_lengths(&neutral);
        assert!(legs.iter().all(|l| l.is_finite()), "neutral legs {legs:?}");
        assert!(
            stewart.fits(&neutral, 0.0),
            "a validated profile whose neutral pose does not fit its legs: {legs:?}"
        );
    }
});
