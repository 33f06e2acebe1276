//! The wire's sample rates and the converter's rates pair up by value, both ways.

use device::{converter_rate, wire_sample_rate};
use fdc1004::Rate;
use wire::SampleRate;

#[test]
fn every_wire_rate_selects_the_converter_rate_of_the_same_value() {
    for rate in [SampleRate::Sps100, SampleRate::Sps200, SampleRate::Sps400] {
        let converter = converter_rate(rate);
        assert_eq!(converter.samples_per_second(), u32::from(rate.sps()));
        assert_eq!(wire_sample_rate(converter), rate);
    }
    for converter in Rate::ALL {
        assert_eq!(converter_rate(wire_sample_rate(converter)), converter);
    }
}
