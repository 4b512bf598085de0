//! Run time against error of the error-free signal, for each motion-model and quadrature
//! setting, on the reference cases sampled at 10, 100 and 1000 Hz (IMU at 1 kHz).
//!
//! `cargo bench --bench accuracy` prints the table docs/motion-model.md shows. Error = max |Δ| of the
//! interval-mean rates against the analytic scene integrated with a 10-node rule (exact to
//! round-off); "interior" leaves out the first and last second.

use std::time::Instant;

use imu_emu::motion::sampled::{Degree, ModelSettings};
use imu_emu::validation::{analytic, compare, rebuild, records, reference_cases, sample_csv};

const IMU_RATE: f64 = 1000.0;

fn main() {
    let models = [
        (
            "cubic/5",
            ModelSettings {
                degree: Degree::Cubic,
                stencil: 5,
            },
        ),
        (
            "quintic/5",
            ModelSettings {
                degree: Degree::Quintic,
                stencil: 5,
            },
        ),
        (
            "quintic/7",
            ModelSettings {
                degree: Degree::Quintic,
                stencil: 7,
            },
        ),
        (
            "quintic/9",
            ModelSettings {
                degree: Degree::Quintic,
                stencil: 9,
            },
        ),
        (
            "quintic/11",
            ModelSettings {
                degree: Degree::Quintic,
                stencil: 11,
            },
        ),
    ];
    println!("IMU at {IMU_RATE} Hz; errors of interval-mean rates against the analytic scene\n");
    println!(
        "| case | input Hz | model | GL nodes | ns/record | gyro max (rad/s) | accel max (m/s²) | gyro interior | accel interior |"
    );
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|");
    for case in reference_cases() {
        let count = (case.duration_s * IMU_RATE) as u64;
        let exact = records(analytic(&case), IMU_RATE, count, 10);
        // Analytic scenes themselves, for the cost of the exact evaluation.
        for nodes in [2, 3] {
            let t = Instant::now();
            let r = records(analytic(&case), IMU_RATE, count, nodes);
            let ns = t.elapsed().as_nanos() as f64 / count as f64;
            let e = compare(&exact, &r);
            println!(
                "| {} | analytic | scene | {nodes} | {ns:.0} | {:.1e} | {:.1e} | {:.1e} | {:.1e} |",
                case.name, e.gyro, e.accel, e.gyro_interior, e.accel_interior
            );
        }
        for input in [10.0, 100.0, 1000.0] {
            let csv = sample_csv(&analytic(&case), input, case.duration_s);
            for (mname, settings) in models {
                for nodes in [2, 3, 4] {
                    let motion = rebuild(&csv, settings);
                    // Best of 3 runs for the time; the records are identical each run.
                    let mut best = f64::INFINITY;
                    let mut r = Vec::new();
                    for _ in 0..3 {
                        let t = Instant::now();
                        r = records(motion.clone(), IMU_RATE, count, nodes);
                        best = best.min(t.elapsed().as_nanos() as f64 / count as f64);
                    }
                    let e = compare(&exact, &r);
                    println!(
                        "| {} | {input} | {mname} | {nodes} | {best:.0} | {:.1e} | {:.1e} | {:.1e} | {:.1e} |",
                        case.name, e.gyro, e.accel, e.gyro_interior, e.accel_interior
                    );
                }
            }
        }
    }
    println!(
        "\nIMU rate = input rate (each interval between two samples), default model, 3 nodes\n"
    );
    println!(
        "| case | rate Hz | gyro max (rad/s) | accel max (m/s²) | gyro interior | accel interior |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    for case in reference_cases() {
        for input in [10.0, 100.0, 1000.0] {
            let count = (case.duration_s * input) as u64;
            let exact = records(analytic(&case), input, count, 10);
            let csv = sample_csv(&analytic(&case), input, case.duration_s);
            let r = records(rebuild(&csv, ModelSettings::default()), input, count, 3);
            let e = compare(&exact, &r);
            println!(
                "| {} | {input} | {:.1e} | {:.1e} | {:.1e} | {:.1e} |",
                case.name, e.gyro, e.accel, e.gyro_interior, e.accel_interior
            );
        }
    }
}
