//! Tests of the simulator against hand-derived expectations: `polycal simulate` with the
//! models and the new forms of the effects, through the binary (only with `cli`). Each
//! model adds its column only when on, a bad value of the new options is one error line
//! and status 2, and `sim-lab` refuses the models it does not simulate (with `lab`).

// ---------------------------------------------------------------- the command line

#[cfg(feature = "cli")]
mod command_line {
    use std::process::{Command, Output};

    fn polycal(args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(args)
            .stdin(std::process::Stdio::null())
            .output()
            .expect("the binary runs")
    }

    fn header(out: &Output) -> String {
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        text.lines()
            .find(|l| !l.starts_with('#'))
            .unwrap_or_default()
            .to_string()
    }

    #[test]
    fn the_models_add_their_columns_only_when_on() {
        let plain = polycal(&["simulate", "--faces", "6", "--cycles", "1"]);
        assert_eq!(plain.status.code(), Some(0));
        assert_eq!(
            header(&plain),
            "cycle,step,ac,face,reading,direction,setup,time,encoder"
        );
        let both = polycal(&[
            "simulate",
            "--faces",
            "6",
            "--cycles",
            "1",
            "--temperature",
            "--elevation",
            "--noise-dof",
            "5",
        ]);
        assert_eq!(
            both.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&both.stderr)
        );
        assert_eq!(
            header(&both),
            "cycle,step,ac,face,reading,direction,setup,time,reading_y,temperature,encoder"
        );
        let warm = polycal(&[
            "simulate",
            "--faces",
            "6",
            "--cycles",
            "1",
            "--temperature",
            "18:1:600:0.2:300",
            "--temperature-effect",
            "1:0.3",
            "--drift",
            "2:0.1:-0.02",
            "--offset-step",
            "1:1:3:0.5",
        ]);
        assert_eq!(
            warm.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&warm.stderr)
        );
        assert_eq!(
            header(&warm),
            "cycle,step,ac,face,reading,direction,setup,time,temperature,encoder"
        );
        // The first data row is at 0 s: 18 °C.
        let text = String::from_utf8_lossy(&warm.stdout).to_string();
        let row = text.lines().filter(|l| !l.starts_with('#')).nth(1).unwrap();
        assert_eq!(row.split(',').nth(8), Some("18"));
    }

    #[test]
    fn bad_values_of_the_new_options_are_one_error_line_and_status_2() {
        for args in [
            &["--noise-dof", "2"][..],
            &["--noise-dof", "abc"],
            &["--temperature", "20:1"],
            &["--temperature", "20:0.5:0:0.1:1200"],
            &["--elevation", "1:2:3"],
            &["--elevation=-1:0:0:0:0"],
            &["--temperature-effect", "1:0.3"],
            &["--cross-talk", "1:0.1"],
            &["--temperature", "--temperature-effect", "3:0.3"],
            &["--elevation", "--cross-talk", "1:x"],
            &["--drift", "1:0.1:nan"],
            &["--offset-step", "1:1:9:0.5"],
            &["--offset-step", "2:1:1:3:0.5"],
        ] {
            let mut all = vec!["simulate", "--faces", "6", "--cycles", "2"];
            all.extend_from_slice(args);
            let out = polycal(&all);
            assert_eq!(out.status.code(), Some(2), "{args:?}");
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
            assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
        }
    }

    #[cfg(feature = "lab")]
    #[test]
    fn sim_lab_refuses_the_models_it_does_not_simulate() {
        let help = polycal(&["sim-lab", "--help"]);
        assert_eq!(help.status.code(), Some(0));
        for args in [
            &["--temperature"][..],
            &["--elevation"],
            &["--noise-dof", "5"],
        ] {
            let mut all = vec!["sim-lab", "--time-scale", "0"];
            all.extend_from_slice(args);
            let out = polycal(&all);
            assert_eq!(out.status.code(), Some(2), "{args:?}");
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
            assert!(stderr.contains("simulated lab"), "{args:?}: {stderr}");
        }
    }
}
