//! The binary refuses out-of-range values at parse time.

#[test]
fn max_clients_outside_one_to_sixty_four_is_refused_when_parsing() {
    for bad in ["0", "65", "1000000", "-1"] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_sim-sensor"))
            .arg(format!("--max-clients={bad}"))
            // Were the value taken, the ports would still be free ones, not the defaults.
            .args([
                "--bind",
                "127.0.0.1:0",
                "--odometry-bind",
                "127.0.0.1:0",
                "--gyro-bind",
                "127.0.0.1:0",
            ])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "--max-clients {bad}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains("--max-clients"),
            "--max-clients {bad}"
        );
    }
}
