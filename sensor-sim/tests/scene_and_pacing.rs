//! Scenes (keyframe interpolation, validation, closures, the serde form of keyframes) and pacing.

use sensor_sim::{Keyframe, Pacing, Scene, SceneError, ScenePoint, ScriptedScene, Simulation};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[test]
fn keyframes_interpolate_linearly_and_hold_at_the_ends() {
    let mut scene = ScriptedScene::new(vec![
        Keyframe::new(1.0, [0.0, 10.0, 0.0, 0.0], 20.0),
        Keyframe::new(3.0, [20.0, 10.0, 0.0, 40.0], 30.0),
        // Two keyframes at one time: a step.
        Keyframe::new(4.0, [20.0, 10.0, 0.0, 40.0], 30.0),
        Keyframe::new(4.0, [0.0; 4], 25.0),
    ])
    .unwrap();
    assert_eq!(
        scene.sample(0),
        ScenePoint::new([0.0, 10.0, 0.0, 0.0], 20.0)
    );
    assert_eq!(
        scene.sample(1_000_000),
        ScenePoint::new([0.0, 10.0, 0.0, 0.0], 20.0)
    );
    assert_eq!(
        scene.sample(2_500_000),
        ScenePoint::new([15.0, 10.0, 0.0, 30.0], 27.5)
    );
    assert_eq!(
        scene.sample(3_999_999).pressure_kpa,
        [20.0, 10.0, 0.0, 40.0]
    );
    assert_eq!(scene.sample(4_000_000), ScenePoint::new([0.0; 4], 25.0));
    assert_eq!(scene.sample(u64::MAX), ScenePoint::new([0.0; 4], 25.0));
    assert_eq!(scene.end_s(), 4.0);
    assert_eq!(scene.keyframes().len(), 4);
}

#[test]
fn invalid_keyframes_are_refused() {
    assert_eq!(ScriptedScene::new(vec![]), Err(SceneError::Empty));
    assert_eq!(
        ScriptedScene::new(vec![
            Keyframe::new(0.0, [0.0; 4], 25.0),
            Keyframe::new(1.0, [f32::NAN, 0.0, 0.0, 0.0], 25.0),
        ]),
        Err(SceneError::NotFinite { index: 1 })
    );
    assert_eq!(
        ScriptedScene::new(vec![
            Keyframe::new(2.0, [0.0; 4], 25.0),
            Keyframe::new(1.0, [0.0; 4], 25.0),
        ]),
        Err(SceneError::TimeGoesBackwards { index: 1 })
    );
}

#[test]
fn keyframes_round_trip_through_serde() {
    let keyframe = Keyframe::new(1.25, [1.0, 2.0, 3.0, 4.5], 31.0);
    let mut buffer = [0u8; 64];
    let bytes = postcard::to_slice(&keyframe, &mut buffer).unwrap();
    let decoded: Keyframe = postcard::from_bytes(bytes).unwrap();
    assert_eq!(decoded, keyframe);
    let point = ScenePoint::new([0.5; 4], 12.0);
    let bytes = postcard::to_slice(&point, &mut buffer).unwrap();
    assert_eq!(postcard::from_bytes::<ScenePoint>(bytes).unwrap(), point);
}

#[test]
fn a_closure_scene_is_sampled_at_conversion_times() {
    let simulation = Simulation::default();
    let samples = Arc::new(AtomicU64::new(0));
    let counter = Arc::clone(&samples);
    simulation.set_scene(move |time_us: u64| {
        counter.fetch_add(1, Ordering::Relaxed);
        ScenePoint::new([0.0; 4], 25.0 + time_us as f32 * 1e-6)
    });
    simulation.advance_us(10_015_500);
    // Only the TMP117 converts (the FDC1004 was never started): at 15.5 ms, then every second.
    assert_eq!(samples.load(Ordering::Relaxed), 11);
    assert_eq!(simulation.scene_point().temperature_c, 25.0 + 10.0155);
}

#[test]
fn a_pacing_callback_sees_every_advance() {
    let simulation = Simulation::default();
    let last_ns = Arc::new(AtomicU64::new(0));
    let seen = Arc::clone(&last_ns);
    simulation
        .set_pacing(Pacing::Callback(Arc::new(move |now_ns| {
            seen.store(now_ns, Ordering::Relaxed);
        })))
        .unwrap();
    simulation.advance_us(1_234);
    assert_eq!(last_ns.load(Ordering::Relaxed), 1_234_000);
    embassy_futures::block_on(embedded_hal_async::delay::DelayNs::delay_us(
        &mut simulation.delay(),
        100,
    ));
    assert_eq!(last_ns.load(Ordering::Relaxed), 1_334_000);
    simulation.set_pacing(Pacing::Off).unwrap();
    simulation.advance_us(1);
    assert_eq!(last_ns.load(Ordering::Relaxed), 1_334_000);
}

#[test]
fn real_time_pacing_refuses_bad_speeds_and_never_runs_ahead_of_the_wall_clock() {
    let simulation = Simulation::default();
    for speed in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(simulation.set_pacing(Pacing::RealTime { speed }).is_err());
    }
    simulation
        .set_pacing(Pacing::RealTime { speed: 2.0 })
        .unwrap();
    let start = Instant::now();
    simulation.advance_us(40_000);
    // A lower bound only: sleeping guarantees at least the time asked for.
    assert!(start.elapsed() >= Duration::from_millis(20));
}

#[test]
fn changing_the_pacing_wakes_a_real_time_sleep_at_once() {
    let simulation = Simulation::default();
    // One simulated second at this speed is a wall-clock day.
    simulation
        .set_pacing(Pacing::RealTime {
            speed: 1.0 / 86_400.0,
        })
        .unwrap();
    let sleeper = simulation.clone();
    let start = Instant::now();
    let advancing = std::thread::spawn(move || sleeper.advance_us(1_000_000));
    std::thread::sleep(Duration::from_millis(50));
    assert!(
        !advancing.is_finished(),
        "the paced advance must be sleeping"
    );
    simulation.set_pacing(Pacing::Off).unwrap();
    while !advancing.is_finished() && start.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(5));
    }
    // Without the wake the thread would sleep for a day; it is left behind and the test fails.
    assert!(
        advancing.is_finished(),
        "the paced sleep was still running 5 s after the pacing was turned off"
    );
    advancing.join().unwrap();
    assert_eq!(simulation.now_us(), 1_000_000);
}
