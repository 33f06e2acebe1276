//! A press, a warm-up and a short, through the model: prints what a user of the pad would see.

use model_core::{
    Calibration, PadModel, SampleInput, TaxelInverses, TaxelReading, TemperatureLaw, Tier,
};

const SENSOR_PF: f32 = 4.5;

fn main() {
    let mut pad = PadModel::new(Calibration::default());
    let law = TemperatureLaw::article_default();
    let reference = TaxelInverses::new(pad.calibration().taxels()[0].curve());
    let reading = |pressure_kpa: f32, temperature_c: f32| {
        let relative_change = reference.relative_change_at(pressure_kpa);
        TaxelReading::CapacitancePf(
            SENSOR_PF * (1.0 + relative_change) * law.permittivity_ratio(temperature_c),
        )
    };
    pad.start_tare(4);
    for _ in 0..4 {
        pad.process(&SampleInput::new([reading(0.0, 25.0); 4], Some(25.0)));
    }
    println!("tier: {}", pad.tier().name());
    println!(
        "{:>8} {:>7}  {:>28}",
        "scene", "temp_c", "c11 c12 c21 c22 (kPa or flags)"
    );
    let scenes: [(&str, [TaxelReading; 4], f32); 5] = [
        (
            "light",
            [
                reading(2.0, 25.0),
                reading(0.0, 25.0),
                reading(0.0, 25.0),
                reading(0.0, 25.0),
            ],
            25.0,
        ),
        ("full", [reading(50.0, 25.0); 4], 25.0),
        ("warm", [reading(20.0, 45.0); 4], 45.0),
        (
            "over",
            [
                reading(50.0, 25.0),
                TaxelReading::CapacitancePf(SENSOR_PF * 1.4),
                reading(0.0, 25.0),
                reading(0.0, 25.0),
            ],
            25.0,
        ),
        (
            "short",
            [
                TaxelReading::CapacitancePf(-0.7),
                reading(10.0, 25.0),
                reading(0.0, 25.0),
                reading(0.0, 25.0),
            ],
            25.0,
        ),
    ];
    for tier in [Tier::MonotoneCubic, Tier::Table] {
        pad.set_tier(tier).unwrap_or_default();
        println!("-- {}", tier.name());
        for (name, readings, temperature_c) in scenes {
            let output = pad.process(&SampleInput::new(readings, Some(temperature_c)));
            let cells: Vec<String> = output
                .taxels
                .iter()
                .map(|taxel| match taxel.pressure_kpa() {
                    Some(kpa) if taxel.flags().is_empty() => format!("{kpa:6.2}"),
                    Some(kpa) => format!("{kpa:6.2} {:?}", taxel.flags()),
                    None => format!("fault {:?}", taxel.flags()),
                })
                .collect();
            println!("{name:>8} {temperature_c:>7.1}  {}", cells.join(" | "));
        }
    }
}
