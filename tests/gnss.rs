//! The GNSS receiver model and the odometer: exact lever arms against closed forms, the epoch
//! grid, the statistics of the injected errors, outages, latency, fix fields and bad settings.

use imu_emu::aiding::gnss::{AntennaState, Fix, GnssConfig, Receiver, displace};
use imu_emu::earth::{self, Geodetic};
use imu_emu::kinematics::Sensed;
use imu_emu::math::{QuatExt, Vec3, quat_from_euler};
use imu_emu::motion::{Motion, Pose};

/// At rest at a fixed place, level, turning about the local vertical at `rate` rad/s
/// (yaw = rate·t): the antenna on a lever arm moves on a circle whose velocity is known.
struct Spin {
    lat: f64,
    lon: f64,
    h: f64,
    rate: f64,
}

impl Motion for Spin {
    fn start(&self) -> f64 {
        0.0
    }
    fn end(&self) -> f64 {
        f64::INFINITY
    }
    fn piece_at(&self, _t: f64, _hint: usize) -> usize {
        0
    }
    fn piece_end(&self, _piece: usize) -> f64 {
        f64::INFINITY
    }
    fn sense(&self, _piece: usize, t: f64) -> Sensed {
        // At rest: ω_ib^b = C_n^b ω_ie^n + ω_nb^b, and ω_nb^b = [0, 0, rate] when level.
        let q = self.pose(t).q_b_n;
        let (s, c) = self.lat.sin_cos();
        Sensed {
            omega_ib_b: q.rotate_inv(earth::omega_ie_n(s, c)) + Vec3::new(0.0, 0.0, self.rate),
            f_b: Vec3::zeros(),
        }
    }
    fn pose(&self, t: f64) -> Pose {
        Pose {
            t,
            lat: self.lat,
            lon: self.lon,
            h: self.h,
            v_n: Vec3::zeros(),
            q_b_n: quat_from_euler(0.0, 0.0, self.rate * t),
        }
    }
}

const SPIN: Spin = Spin {
    lat: 0.72,
    lon: 0.035,
    h: 250.0,
    rate: 0.5,
};

fn quiet() -> GnssConfig {
    GnssConfig {
        pos_white_m: [0.0; 3],
        pos_gm_m: [0.0; 3],
        vel_white_m_s: [0.0; 3],
        vel_gm_m_s: [0.0; 3],
        ..GnssConfig::default()
    }
}

fn ecef(s: &AntennaState) -> Vec3 {
    Geodetic::from_radians(s.lat, s.lon, s.h).to_ecef()
}

/// A lever arm of 2 m along body x on a vehicle yawing at Ω: the antenna is 2 m from the
/// reference point along the heading, and moves at Ω·2 m/s perpendicular to it:
/// v = Ω ẑ × C_b^n l = 2Ω[−sin ψ, cos ψ, 0] in the vehicle's NED, the same vector in ECEF as
/// the antenna's NED velocity rotated by the antenna's own C_n^e.
#[test]
fn lever_arm_on_a_turning_vehicle_matches_the_circle() {
    let cfg = GnssConfig {
        lever_arm_m: [2.0, 0.0, 0.0],
        rate_hz: 10.0,
        ..quiet()
    };
    let epochs = Receiver::new(cfg, 1).unwrap().epochs(&SPIN, 0.0, 13.0);
    assert_eq!(epochs.len(), 131);
    let veh = Geodetic::from_radians(SPIN.lat, SPIN.lon, SPIN.h);
    let c_ne = veh.c_n_e();
    for e in &epochs {
        let psi = SPIN.rate * e.t;
        let offset = c_ne * Vec3::new(2.0 * psi.cos(), 2.0 * psi.sin(), 0.0);
        let dr = ecef(&e.truth) - veh.to_ecef() - offset;
        assert!(dr.amax() < 1e-8, "t {} position off by {dr:?} m", e.t);
        let v_expected = c_ne
            * (Vec3::new(
                -2.0 * SPIN.rate * psi.sin(),
                2.0 * SPIN.rate * psi.cos(),
                0.0,
            ));
        let ant = Geodetic::from_radians(e.truth.lat, e.truth.lon, e.truth.h);
        let dv = ant.c_n_e() * e.truth.v_n - v_expected;
        assert!(dv.amax() < 1e-14, "t {} velocity off by {dv:?} m/s", e.t);
        assert_eq!(e.measured, e.truth, "no errors configured");
    }
}

/// An antenna 3 m above a level vehicle is 3 m higher at the same latitude and longitude, and
/// turning about the vertical does not move it.
#[test]
fn vertical_lever_arm_adds_height_only() {
    let cfg = GnssConfig {
        lever_arm_m: [0.0, 0.0, -3.0],
        ..quiet()
    };
    for e in Receiver::new(cfg, 1).unwrap().epochs(&SPIN, 0.0, 5.0) {
        assert!((e.truth.h - (SPIN.h + 3.0)).abs() < 1e-8, "{}", e.truth.h);
        assert!((e.truth.lat - SPIN.lat).abs() < 1e-15);
        assert!((e.truth.lon - SPIN.lon).abs() < 1e-15);
        assert!(e.truth.v_n.amax() < 1e-15, "{:?}", e.truth.v_n);
    }
}

/// Epochs fall on whole multiples of 1/rate from the first at or after the start, each
/// emitted `latency` later.
#[test]
fn epoch_grid_and_latency() {
    let cfg = GnssConfig {
        rate_hz: 4.0,
        latency_s: 0.08,
        ..quiet()
    };
    let e = Receiver::new(cfg, 1).unwrap().epochs(&SPIN, 0.3, 2.0);
    let t: Vec<f64> = e.iter().map(|e| e.t).collect();
    assert_eq!(t, [0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0]);
    assert_eq!(e[0].k, 2);
    for e in &e {
        assert_eq!(e.t_emit, e.t + 0.08);
    }
}

/// The NED displacement is applied on the local radii of curvature: moving back by the same
/// metres recovers the position, and a north step of R_N+h metres is one radian of latitude.
#[test]
fn displacement_uses_the_radii_of_curvature() {
    let s = AntennaState {
        lat: 0.5,
        lon: 1.0,
        h: 100.0,
        v_n: Vec3::new(1.0, 2.0, 3.0),
    };
    let rn = earth::radius_meridian(0.5f64.sin()) + 100.0;
    let re = earth::radius_prime_vertical(0.5f64.sin()) + 100.0;
    let d = displace(
        s,
        Vec3::new(rn * 1e-6, re * 0.5f64.cos() * 2e-6, -4.0),
        Vec3::new(0.1, 0.2, 0.3),
    );
    assert!((d.lat - (0.5 + 1e-6)).abs() < 1e-15);
    assert!((d.lon - (1.0 + 2e-6)).abs() < 1e-15);
    assert_eq!(d.h, 104.0);
    assert_eq!(d.v_n, Vec3::new(1.1, 2.2, 3.3));
}

/// Sample variance and lag-1 autocorrelation of one error component.
fn var_r1(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|a| (a - m) * (a - m)).sum::<f64>() / n;
    let c1 = x.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum::<f64>() / n;
    (v, c1 / v)
}

/// N epochs at 10 Hz.
const N: usize = 20_001;

fn errors(cfg: GnssConfig, seed: u64) -> Vec<imu_emu::aiding::GnssEpoch> {
    let e = Receiver::new(cfg, seed).unwrap().epochs(&SPIN, 0.0, 2000.0);
    assert_eq!(e.len(), N);
    e
}

/// White errors: per axis the sample variance is σ² and neighbours are uncorrelated.
/// Tolerances, 4σ of the estimators for N independent normal draws: the sample variance has
/// relative standard deviation √(2/N) = 0.0100, the lag-1 autocorrelation 1/√N = 0.0071.
/// Reported positions and velocities are the truth moved by exactly these errors.
#[test]
fn white_errors_have_their_sigma_and_no_memory() {
    let cfg = GnssConfig {
        rate_hz: 10.0,
        pos_white_m: [1.0, 2.0, 3.0],
        vel_white_m_s: [0.1, 0.2, 0.3],
        ..quiet()
    };
    let e = errors(cfg.clone(), 7);
    let n = N as f64;
    for i in 0..3 {
        for (sigma, x) in [
            (
                cfg.pos_white_m[i],
                e.iter().map(|e| e.pos_err_n[i]).collect::<Vec<_>>(),
            ),
            (
                cfg.vel_white_m_s[i],
                e.iter().map(|e| e.vel_err_n[i]).collect(),
            ),
        ] {
            let (v, r1) = var_r1(&x);
            assert!(
                (v / (sigma * sigma) - 1.0).abs() < 4.0 * (2.0 / n).sqrt(),
                "axis {i}: var {v} for σ {sigma}"
            );
            assert!(
                r1.abs() < 4.0 / n.sqrt(),
                "axis {i}: lag-1 correlation {r1}"
            );
        }
    }
    for e in &e {
        let d = displace(e.truth, e.pos_err_n, e.vel_err_n);
        assert_eq!(d, e.measured);
    }
    // The streams are named per axis: the north and east errors are not the same draws.
    assert_ne!(e[5].pos_err_n.x / 1.0, e[5].pos_err_n.y / 2.0);
}

/// First-order Gauss–Markov errors: stationary variance σ² and lag-1 autocorrelation
/// φ = e^{−Δt/τ}; with τ = Δt/ln 2, φ = 0.5. For an AR(1) sequence of N samples the sample
/// variance has relative standard deviation √(2(1+φ²)/(N(1−φ²))) = 0.0129 and the lag-1
/// autocorrelation standard deviation √((1−φ²)/N) = 0.0061 (Bartlett); tolerances are 4σ.
#[test]
fn gauss_markov_errors_have_their_sigma_and_correlation() {
    let dt = 0.1;
    let tau = dt / std::f64::consts::LN_2;
    let cfg = GnssConfig {
        rate_hz: 10.0,
        pos_gm_m: [1.0, 2.0, 3.0],
        pos_gm_tau_s: [tau; 3],
        vel_gm_m_s: [0.1, 0.2, 0.3],
        vel_gm_tau_s: [tau; 3],
        ..quiet()
    };
    let e = errors(cfg.clone(), 11);
    let (n, phi) = (N as f64, 0.5f64);
    let tol_v = 4.0 * (2.0 * (1.0 + phi * phi) / (n * (1.0 - phi * phi))).sqrt();
    let tol_r = 4.0 * ((1.0 - phi * phi) / n).sqrt();
    for i in 0..3 {
        for (sigma, x) in [
            (
                cfg.pos_gm_m[i],
                e.iter().map(|e| e.pos_err_n[i]).collect::<Vec<_>>(),
            ),
            (
                cfg.vel_gm_m_s[i],
                e.iter().map(|e| e.vel_err_n[i]).collect(),
            ),
        ] {
            let (v, r1) = var_r1(&x);
            assert!(
                (v / (sigma * sigma) - 1.0).abs() < tol_v,
                "axis {i}: var {v} for σ {sigma}"
            );
            assert!(
                (r1 - phi).abs() < tol_r,
                "axis {i}: lag-1 correlation {r1}, expected {phi}"
            );
        }
    }
}

/// In an outage window there is no fix and no satellite; the errors keep running, so every
/// epoch outside the window is the same as without the outage. The same seed gives the same
/// epochs, another seed other errors.
#[test]
fn outages_remove_the_fix_only() {
    let base = GnssConfig {
        rate_hz: 10.0,
        ..GnssConfig::default()
    };
    let cut = GnssConfig {
        outages_s: vec![[10.0, 20.0]],
        ..base.clone()
    };
    let a = Receiver::new(base.clone(), 3)
        .unwrap()
        .epochs(&SPIN, 0.0, 30.0);
    let b = Receiver::new(cut, 3).unwrap().epochs(&SPIN, 0.0, 30.0);
    assert_eq!(a.len(), b.len());
    let mut lost = 0;
    for (a, b) in a.iter().zip(&b) {
        if (10.0..20.0).contains(&b.t) {
            lost += 1;
            assert_eq!((b.fix, b.satellites), (Fix::None, 0));
            assert_eq!(b.pos_err_n, a.pos_err_n);
        } else {
            assert_eq!(a, b);
            assert_ne!(b.fix, Fix::None);
            assert_eq!(b.satellites, 12);
        }
    }
    assert_eq!(lost, 100);
    let c = Receiver::new(base, 4).unwrap().epochs(&SPIN, 0.0, 30.0);
    assert_ne!(c[0].pos_err_n, a[0].pos_err_n);
}

/// The fix kind, accuracies and dilutions follow the configured errors.
#[test]
fn fix_fields_follow_the_errors() {
    let rtk = GnssConfig {
        pos_white_m: [0.02, 0.02, 0.03],
        pos_gm_m: [0.0; 3],
        uere_m: 0.02,
        ..GnssConfig::default()
    };
    let e = Receiver::new(rtk, 1).unwrap().epochs(&SPIN, 0.0, 0.0)[0];
    assert_eq!(e.fix, Fix::RtkFixed);
    assert!((e.hdop - 0.02f64.hypot(0.02) / 0.02).abs() < 1e-15);
    assert!((e.vdop - 1.5).abs() < 1e-15);
    let sps = GnssConfig::default();
    let s = sps.sigma_pos();
    assert_eq!(
        s,
        Vec3::new(0.5f64.hypot(1.0), 0.5f64.hypot(1.0), 1.0f64.hypot(2.0))
    );
    assert_eq!(sps.fix_kind(), Fix::Autonomous);
    for (sigma_h, fix) in [
        (0.05, Fix::RtkFixed),
        (0.06, Fix::RtkFloat),
        (0.5, Fix::RtkFloat),
        (1.5, Fix::Differential),
        (1.6, Fix::Autonomous),
    ] {
        assert_eq!(Fix::for_horizontal_sigma(sigma_h), fix, "{sigma_h}");
    }
}

/// Every bad setting is refused with the `[gnss]` key it came from.
#[test]
fn bad_settings_name_their_key() {
    let cases: Vec<(GnssConfig, &str)> = vec![
        (
            GnssConfig {
                rate_hz: 25.0,
                ..Default::default()
            },
            "gnss.rate_hz",
        ),
        (
            GnssConfig {
                rate_hz: f64::NAN,
                ..Default::default()
            },
            "gnss.rate_hz",
        ),
        (
            GnssConfig {
                pos_white_m: [1.0, -1.0, 0.0],
                ..Default::default()
            },
            "gnss.pos_white_m",
        ),
        (
            GnssConfig {
                lever_arm_m: [f64::INFINITY, 0.0, 0.0],
                ..Default::default()
            },
            "gnss.lever_arm_m",
        ),
        (
            GnssConfig {
                vel_gm_tau_s: [1.0, 0.0, 1.0],
                ..Default::default()
            },
            "gnss.vel_gm_tau_s",
        ),
        (
            GnssConfig {
                latency_s: -0.1,
                ..Default::default()
            },
            "gnss.latency_s",
        ),
        (
            GnssConfig {
                outages_s: vec![[5.0, 5.0]],
                ..Default::default()
            },
            "gnss.outages_s",
        ),
        (
            GnssConfig {
                satellites: 3,
                ..Default::default()
            },
            "gnss.satellites",
        ),
        (
            GnssConfig {
                uere_m: 0.0,
                ..Default::default()
            },
            "gnss.uere_m",
        ),
        (
            GnssConfig {
                leap_seconds: -1,
                ..Default::default()
            },
            "gnss.leap_seconds",
        ),
    ];
    for (cfg, key) in cases {
        let err = Receiver::new(cfg, 1).unwrap_err().to_string();
        assert!(err.starts_with(&format!("{key}: ")), "{err}");
    }
}

/// A wheel 0.8 m left of the reference point (l = [0, −0.8, 1]) of a vehicle yawing at Ω at
/// rest rolls forward at −Ω·l_y = 0.4 m/s (ω × l = [−Ω l_y, Ω l_x, 0]). With 97 ticks/m and a
/// +1 % scale factor the count at t is ⌊0.4·t·1.01·97⌋; a slip of +0.5 from 2 s to 4 s adds
/// half of the distance rolled in it. A wheel on the other side counts backwards.
#[test]
fn odometer_counts_the_rolled_distance() {
    use imu_emu::aiding::odometer::{Odometer, OdometerConfig};
    let cfg = OdometerConfig {
        rate_hz: 10.0,
        counts_per_m: 97.0,
        scale_factor: 0.01,
        lever_arm_m: [0.0, -0.8, 1.0],
        slip: vec![[2.0, 4.0, 0.5]],
    };
    let mut odo = Odometer::new(cfg.clone());
    let mut prev = 0;
    for k in 1..=60 {
        let t = k as f64 * 0.1;
        let s = odo.sample(&SPIN, t - 0.1, t);
        assert!(
            (s.true_distance_m - 0.04).abs() < 1e-15,
            "{}",
            s.true_distance_m
        );
        let slipped = 0.5 * 0.4 * (t.min(4.0) - 2.0).max(0.0);
        let expected = ((0.4 * t + slipped) * 1.01 * 97.0 + 1e-9).floor() as i64;
        assert_eq!(s.ticks, expected, "t {t}");
        assert_eq!(s.delta_ticks, s.ticks - prev);
        assert!((s.speed_m_s - s.delta_ticks as f64 / 9.7).abs() < 1e-12);
        prev = s.ticks;
    }
    let mut right = Odometer::new(OdometerConfig {
        lever_arm_m: [0.0, 0.8, 1.0],
        ..cfg
    });
    assert!((right.forward_speed(&SPIN, 1.0) + 0.4).abs() < 1e-15);
    assert_eq!(
        right.sample(&SPIN, 0.0, 1.0).ticks,
        (-0.4f64 * 1.01 * 97.0).floor() as i64
    );
}

/// A simulation's GNSS stream runs on its motion and GPS time: with no lever arm the truth is
/// the trajectory's pose at each epoch, the epochs cover the run's span, and the NMEA time is
/// the run's GPS reference in UTC (week 2300, second 100 000 = 2024-02-05 03:46:22 UTC).
#[test]
fn simulation_gnss_follows_its_motion_and_clock() {
    let sim = imu_emu::sim::Simulation::builder()
        .scene("circle")
        .duration(2.0)
        .gps_time(2300, 100_000.0)
        .gnss(GnssConfig {
            rate_hz: 2.0,
            ..GnssConfig::default()
        })
        .build()
        .unwrap();
    let epochs = sim.gnss_receiver().epochs(sim.motion(), 0.0, 2.0);
    assert_eq!(epochs.len(), 5);
    for e in &epochs {
        let p = sim.motion().pose(e.t);
        assert_eq!(
            (e.truth.lat, e.truth.lon, e.truth.h, e.truth.v_n),
            (p.lat, p.lon, p.h, p.v_n)
        );
    }
    let (mut nmea, mut truth) = (Vec::new(), Vec::new());
    let n = sim
        .write_gnss(
            &mut [(imu_emu::aiding::GnssFormat::Nmea, &mut nmea)],
            Some(&mut truth),
        )
        .unwrap();
    assert_eq!(n, 5);
    let nmea = String::from_utf8(nmea).unwrap();
    assert!(nmea.starts_with("$GPGGA,034622.00,"), "{nmea}");
    assert!(
        nmea.contains("$GPZDA,034624.00,05,02,2024,00,00*"),
        "{nmea}"
    );
    assert_eq!(String::from_utf8(truth).unwrap().lines().count(), 1 + 5);
}

/// With record time 0 at a fractional GPS second (a run started at 100 000.37 s of the week),
/// the epochs fall on whole multiples of 1/rate of GPS time, as a receiver reports, not of
/// record time; the planned count is the number written, and the NMEA time reads .00 or .50.
#[test]
fn epochs_fall_on_the_gps_time_grid() {
    let sim = imu_emu::sim::Simulation::builder()
        .scene("circle")
        .duration(3.0)
        .gps_time(2300, 100_000.37)
        .gnss(GnssConfig {
            rate_hz: 2.0,
            ..GnssConfig::default()
        })
        .build()
        .unwrap();
    let epochs = sim.gnss_receiver().epochs(sim.motion(), 0.0, 3.0);
    let t: Vec<f64> = epochs.iter().map(|e| e.t).collect();
    let expected = [0.13, 0.63, 1.13, 1.63, 2.13, 2.63];
    assert_eq!(t.len(), expected.len(), "{t:?}");
    for (t, x) in t.iter().zip(expected) {
        // Record time from GPS time: 100 000.5 − 100 000.37 rounds in the last bits.
        assert!((t - x).abs() < 1e-9, "{t} {x}");
        let gps = 100_000.37 + t;
        assert!(
            (gps * 2.0 - (gps * 2.0).round()).abs() < 1e-9,
            "GPS time {gps}"
        );
    }
    assert_eq!(sim.gnss_epochs(), 6);
    let mut nmea = Vec::new();
    let n = sim
        .write_gnss(&mut [(imu_emu::aiding::GnssFormat::Nmea, &mut nmea)], None)
        .unwrap();
    assert_eq!(n, 6);
    let nmea = String::from_utf8(nmea).unwrap();
    for line in nmea.lines().filter(|l| l.starts_with("$GPGGA")) {
        let time = line.split(',').nth(1).unwrap();
        assert!(time.ends_with(".00") || time.ends_with(".50"), "{line}");
    }
}
