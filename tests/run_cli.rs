//! `tumble run`: JSON summary against the physics, and a trajectory that survives Ctrl-C.
#![cfg(feature = "cli")]
use std::process::Command;

fn tumble() -> Command {
    Command::new(env!("CARGO_BIN_EXE_tumble"))
}

/// A fresh, empty folder for one test's files.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("tumble-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `command` and returns its output, failing with its stderr if it did not succeed.
fn succeeded(command: &mut Command) -> std::process::Output {
    let out = command.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn json_summary_has_the_documented_fields() {
    let out = succeeded(tumble().args(["run", "two-chain", "--steps", "50", "--json"]));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "steps",
        "sim_time",
        "wall_s",
        "steps_per_s",
        "bodies",
        "contacts",
        "constraint_visits",
        "budget_hits",
        "joint_projections_cut_short",
        "energy_start",
        "energy_end",
        "max_penetration",
        "max_constraint_violation",
        "max_relative_constraint_violation",
        "finite",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["steps"], 50);
    // Nothing frozen: 0, not the -0.0 an empty sum of floats gives.
    assert!(v["energy_frozen"].as_f64().unwrap().is_sign_positive());
    assert!(
        (v["sim_time"].as_f64().unwrap() - 1.0).abs() < 1e-9,
        "50 steps of 0.02 s"
    );
    assert_eq!(v["bodies"], 18);
    // The scene's constraint file holds 16 records, each a lower and an upper inequality.
    let file = std::fs::read_to_string("scenes/two-chain-constraints.txt").unwrap();
    let declared = file.lines().find(|l| !l.starts_with('#')).unwrap().trim();
    assert_eq!(v["constraint_records"].to_string(), declared);
    assert_eq!(
        v["constraints"],
        2 * v["constraint_records"].as_u64().unwrap()
    );
    assert_eq!(v["finite"], true);
}

/// A rope too long for its step under the soft step (rope-500 at dt 0.4, where its 16 substeps,
/// the most a scene with distance constraints is raised to, are 1/40 s long: after 37 steps
/// its links turn too far within one for the projections' rounds) is reported as such in
/// the JSON summary; a rope the step holds reports none, in words.
/// `--accurate` takes four substeps a step from dt 0.01 up and two at dt 0.005 (the mixed
/// scene's first tenth of a second: nothing touches yet, and no constraint raises the count);
/// `--full-substeps-from 0` keeps all four.
#[test]
fn short_steps_take_fewer_substeps_unless_told_otherwise() {
    let substeps = |extra: &[&str]| {
        let mut args = vec!["run", "mixed", "--accurate", "--json"];
        args.extend_from_slice(extra);
        let out = succeeded(tumble().args(&args));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["substeps_taken"].as_u64().unwrap()
    };
    assert_eq!(substeps(&["--dt", "0.01", "--steps", "10"]), 40);
    assert_eq!(substeps(&["--dt", "0.005", "--steps", "20"]), 40);
    let all = [
        "--dt",
        "0.005",
        "--steps",
        "20",
        "--full-substeps-from",
        "0",
    ];
    assert_eq!(substeps(&all), 80);
}

#[test]
fn joint_projections_cut_short_are_reported() {
    let run = |scene: &str, steps: &str, json: bool| {
        let mut args = vec!["run", scene, "--accurate", "--dt", "0.4", "--steps", steps];
        if json {
            args.push("--json");
        }
        String::from_utf8_lossy(&succeeded(tumble().args(args)).stdout).into_owned()
    };
    let v: serde_json::Value = serde_json::from_str(&run("rope-500", "45", true)).unwrap();
    let cut_short = v["joint_projections_cut_short"].as_u64().unwrap();
    assert!(cut_short > 0, "{v}");
    let held = run("rope-20", "10", false);
    assert!(held.contains("joint projections cut short 0,"), "{held}");
}

/// A step a billion seconds long throws every body far past any sane speed: the run still ends
/// normally, says which bodies blew up and that they were frozen, and its summary says the
/// values were not all finite and why.
#[test]
fn bodies_that_blow_up_are_named_and_the_run_goes_on() {
    let out = succeeded(tumble().args([
        "run",
        "pile-20",
        "--accurate",
        "--dt",
        "1e9",
        "--steps",
        "3",
    ]));
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(
        stderr.contains("warning: body 4 blew up at step 2") && stderr.contains("frozen"),
        "{stderr}"
    );
    // Ten by name, then one line for the rest (not one for each of the twenty).
    assert_eq!(stderr.matches("blew up at step").count(), 10, "{stderr}");
    assert_eq!(stderr.matches("more bodies blew up").count(), 1, "{stderr}");
    assert!(
        stdout.contains("all values finite: false (20 bodies blew up and were frozen: 4, 5,"),
        "{stdout}"
    );
    assert!(
        stdout.contains("the end leaves out 20 frozen bodies, potential energy"),
        "{stdout}"
    );
    // One body of 3e306 units of energy: its loss is -100 % (a hundred times its energy
    // overflowed to -inf %), and it was frozen, in the singular.
    let heavy = ["run", "stack-1", "--steps", "20", "--gravity", "0,-2e304,0"];
    let out = succeeded(tumble().args(heavy));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("(-100.000%; the end leaves out 1 frozen body, potential energy 3.0"),
        "{stdout}"
    );
    assert!(
        stdout.contains("(1 body blew up and was frozen: 0)"),
        "{stdout}"
    );
}

/// The text summary stays readable at any size: a change of energy past a billion percent and
/// a violation of a billion units in scientific notation (twenty digits before), one step in
/// the singular.
#[test]
fn the_summary_writes_huge_figures_shortly() {
    let out = succeeded(tumble().args(["run", "cube", "--dt", "1e9", "--steps", "3"]));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = |start: &str| stdout.lines().find(|l| l.starts_with(start)).unwrap();
    let energy = line("energy ");
    let change = &energy[energy.find('(').unwrap() + 1..energy.find("%)").unwrap()];
    let value: f64 = change.parse().unwrap();
    assert!(value > 1e9 && change.len() < 12, "{energy}");
    let visits = line("constraint visits");
    let worst = visits.rsplit("worst violation ").next().unwrap();
    let (worst, share) = worst.split_once(", ").unwrap();
    assert!(
        share.starts_with("worst share of a rest length "),
        "{visits}"
    );
    assert!(
        worst.parse::<f64>().unwrap() > 1e9 && worst.len() < 14,
        "{visits}"
    );
    let out = succeeded(tumble().args(["run", "cube", "--steps", "1"]));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("\n1 step (0.02 s simulated)"), "{stdout}");
    // An energy past f64's range has no share of change (it printed "NaN%").
    let args = ["run", "mixed", "--steps", "2", "--gravity", "0,-1e308,0"];
    let out = succeeded(tumble().args(args));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let energy = stdout.lines().find(|l| l.starts_with("energy ")).unwrap();
    assert!(
        energy.contains("no change to give") && !energy.contains("NaN"),
        "{energy}"
    );
}

#[cfg(unix)]
#[test]
fn trajectory_survives_ctrl_c() {
    // And SIGTERM (`timeout`'s), which left the partial file behind.
    for (signal, status) in [(libc::SIGINT, 130), (libc::SIGTERM, 143)] {
        trajectory_survives(signal, status);
    }
}

/// A second Ctrl-C a moment after the first stops the run at once, in the middle of a step
/// that would take seconds (two records that no distance satisfies, and the largest budget,
/// 1e9: about 6 s a step here, where the signals come at 1.5 s and 1.8 s); the first alone only
/// asks it to finish the step.
#[cfg(unix)]
#[test]
fn a_later_signal_stops_at_once() {
    use std::os::unix::process::ExitStatusExt;
    let dir = scratch("run-later");
    let box_mesh = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/box.mesh");
    std::fs::copy(box_mesh, dir.join("box.mesh")).unwrap();
    let scene = dir.join("c-scene.txt");
    let bodies = "2\nbox.mesh 1 0 0 3 0 1 0 0 0\nbox.mesh 1 0 0 8 0 1 0 0 0\n";
    std::fs::write(&scene, bodies).unwrap();
    let records = "2\n0 0 1 0 0.5 0.6\n0 0 1 0 1.4 1.5\n";
    std::fs::write(dir.join("c-constraints.txt"), records).unwrap();
    let mut child = tumble()
        .arg("run")
        .arg(&scene)
        .args(["--max-iterations", "1000000000", "--steps", "2"])
        .stderr(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    for pause in [300, 0] {
        // SAFETY: sending a signal to our own child process.
        unsafe {
            libc::kill(child.id() as libc::pid_t, libc::SIGINT);
        }
        std::thread::sleep(std::time::Duration::from_millis(pause));
    }
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() && start.elapsed().as_secs() < 20 {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let _ = child.kill();
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.signal(), Some(libc::SIGINT), "{stderr}");
    assert!(
        stderr.contains("interrupted: finishing the current step"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn trajectory_survives(signal: libc::c_int, status: i32) {
    let dir = scratch(&format!("run-sig{signal}"));
    let out = dir.join("trajectory.csv");
    let child = tumble()
        .args(["run", "pile-500", "--steps", "100000000", "--trajectory"])
        .arg(&out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    // Twice at once, as GNU `timeout` sends it (to the command, then to its process group): the
    // copy is not the second signal that stops at once.
    for _ in 0..2 {
        // SAFETY: sending a signal to our own child process.
        unsafe {
            libc::kill(child.id() as libc::pid_t, signal);
        }
    }
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(status), "{stderr}");
    assert!(stderr.contains("interrupted after"), "{stderr}");
    // Said at once, with how to stop without waiting.
    assert!(
        stderr.contains("press Ctrl-C again to stop at once"),
        "{stderr}"
    );
    // Every completed step is there, whole: step 0 plus each step, 504 bodies each.
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = text.lines().skip(1).collect();
    assert!(
        rows.len() >= 2 * 504 && rows.len().is_multiple_of(504),
        "{} rows",
        rows.len()
    );
    for row in &rows {
        assert_eq!(row.split(',').count(), 10, "incomplete row {row}");
    }
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "left behind: {names:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench accuracy` writes its JSON beside its CSV, from the same run: every CSV row's value is
/// in the JSON under scenario -> combination -> dt -> metrics. The table file holds the table,
/// and standard output names every file written.
#[test]
fn bench_accuracy_json_beside_the_csv_matches_it() {
    let dir = scratch("bench-json");
    let out = succeeded(
        tumble()
            .args([
                "bench",
                "accuracy",
                "--scenarios",
                "free-fall",
                "--dts",
                "0.04",
            ])
            // Named time steps and combinations are run as named, --quick or not (it ran
            // dt 0.01 too).
            .args([
                "--quick",
                "--combinations",
                "coursework,gyroscopic",
                "--out",
            ])
            .arg(&dir),
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("accuracy.json")).unwrap()).unwrap();
    let csv = std::fs::read_to_string(dir.join("accuracy.csv")).unwrap();
    let mut rows = 0;
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let (scenario, combination, dt, metric) = (f[0], f[1], f[2], f[4]);
        let value: f64 = f[5].parse().unwrap();
        let in_json = json[scenario][combination][dt]["metrics"][metric]
            .as_f64()
            .unwrap();
        assert!(
            (in_json - value).abs() <= 1e-6 * value.abs().max(1e-300),
            "{line}"
        );
        rows += 1;
    }
    assert_eq!(rows, 2, "one metric per combination:\n{csv}");
    for combination in ["coursework", "gyroscopic"] {
        let dts: Vec<&String> = json["free_fall"][combination]
            .as_object()
            .unwrap()
            .keys()
            .collect();
        assert_eq!(dts, ["0.04"], "{combination}");
    }
    // The table printed is written beside them too, each value as the JSON holds it.
    let table = std::fs::read_to_string(dir.join("accuracy.txt")).unwrap();
    assert!(table.contains("free_fall (position_error"), "{table}");
    for combination in ["coursework", "gyroscopic"] {
        let row = table.lines().find(|l| l.starts_with(combination)).unwrap();
        let value = json["free_fall"][combination]["0.04"]["metrics"]["position_error"]
            .as_f64()
            .unwrap();
        assert!(row.contains(&format!("{value:.3e}")), "{row}");
    }
    // The table file holds the table; standard output names the files written, one line for
    // the CSV, JSON and table, then one a plot, each a file that exists.
    assert!(!table.contains("wrote"), "{table}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let written: Vec<&str> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("wrote "))
        .collect();
    let name = |file: &str| dir.join(file).display().to_string();
    let beside = format!(
        "{}, {} and {}",
        name("accuracy.csv"),
        name("accuracy.json"),
        name("accuracy.txt")
    );
    assert_eq!(written.first(), Some(&beside.as_str()), "{stdout}");
    assert_eq!(written.len(), 2, "one plot for one scenario: {stdout}");
    assert_eq!(written[1], name("accuracy-free_fall.svg"), "{stdout}");
    assert!(dir.join("accuracy-free_fall.svg").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench scale --quick` shortens what is not given; sizes and steps given are run as given.
#[test]
fn bench_scale_quick_keeps_what_is_named() {
    let dir = scratch("scale-quick");
    let out = succeeded(
        tumble()
            .args([
                "bench", "scale", "--quick", "--scenes", "pile", "--sizes", "20",
            ])
            .args([
                "--variants",
                "tumble_1_thread",
                "--steps",
                "3",
                "--json",
                "--out",
            ])
            .arg(&dir),
    );
    let _ = std::fs::remove_dir_all(&dir);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let scenes: Vec<&String> = v["results"].as_object().unwrap().keys().collect();
    assert_eq!(scenes, ["pile-20"]);
    assert_eq!(v["steps"], 3);
}

/// A bench's folder holds one run: a second run into it removes the plots of the families the
/// first ran and it does not (they stayed beside a report without them); a variant or size
/// named twice runs once (its runs were counted twice); a run with nothing to measure, a report
/// name taken by a folder and `--out` naming a file are refused before anything runs.
#[test]
fn bench_folders_hold_one_run() {
    let dir = scratch("bench-folder");
    let scale = |scenes: &str, variants: &str| {
        let mut command = tumble();
        command
            .args(["bench", "scale", "--quick", "--scenes", scenes])
            .args(["--sizes", "10,10", "--variants", variants, "--steps", "3"])
            .args(["--json", "--out"])
            .arg(&dir);
        command
    };
    succeeded(&mut scale("sparse,chain", "tumble_1_thread"));
    assert!(dir.join("scale-chain.svg").is_file());
    let again = succeeded(&mut scale("sparse", "tumble_1_thread,tumble_1_thread"));
    assert!(!dir.join("scale-chain.svg").exists());
    assert!(dir.join("scale-sparse.svg").is_file());
    let v: serde_json::Value = serde_json::from_slice(&again.stdout).unwrap();
    let run = &v["results"]["sparse-10"]["tumble_1_thread"];
    assert!(run["runs"].as_u64().unwrap() <= 5, "{run}");
    let refused = |command: &mut Command, words: &str| {
        let out = command.output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(words), "{stderr}");
    };
    let mut nothing = tumble();
    nothing
        .args(["bench", "scale", "--quick", "--scenes", "scatter"])
        .args([
            "--scatter-sizes",
            "20000",
            "--variants",
            "coursework",
            "--out",
        ])
        .arg(&dir);
    refused(&mut nothing, "nothing to measure");
    std::fs::remove_file(dir.join("scale.json")).unwrap();
    std::fs::create_dir_all(dir.join("scale.json")).unwrap();
    refused(
        &mut scale("sparse", "tumble_1_thread"),
        "scale.json there is a folder",
    );
    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    let mut into_file = tumble();
    into_file
        .args(["bench", "scale", "--quick", "--out"])
        .arg(&file);
    refused(&mut into_file, "a file is there");
    refused(
        tumble().args(["bench", "soak", "--steps", "0"]),
        "at least 1",
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--gravity` pulls every body the way it says: the cube scene's eight octahedra, held
/// rigidly together, fall sideways as one, by semi-implicit Euler's `g dt^2 n (n + 1) / 2`
/// after n steps, and not at all along y. The trajectory written to standard output is the
/// file's.
/// A scene or settings flags given without a command are told which command takes them;
/// another mistake gets clap's message alone (an argument that is not UTF-8 too, where the
/// hint's reading of the arguments must not panic); every one exits with status 2.
#[test]
fn a_scene_or_flags_without_a_command_name_the_command() {
    let stderr = |command: &mut Command| {
        let out = command.output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{command:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    assert!(stderr(tumble().arg("tower")).contains("`tumble view tower` shows it"));
    let pile = stderr(tumble().arg("pile-300"));
    assert!(
        pile.contains("`tumble run pile-300` runs it headless"),
        "{pile}"
    );
    let flags = stderr(tumble().args(["--accurate", "--dt", "0.01"]));
    assert!(flags.contains("`tumble view --accurate ...`"), "{flags}");
    #[cfg(unix)]
    let not_utf8 = {
        use std::os::unix::ffi::OsStrExt;
        std::ffi::OsStr::from_bytes(b"caf\xe9-scene.txt").to_owned()
    };
    #[cfg(not(unix))]
    let not_utf8 = std::ffi::OsString::from("caf-scene.txt");
    for other in [
        tumble().arg("--verison"),
        tumble().arg("towr"),
        tumble().arg(not_utf8),
    ] {
        let text = stderr(other);
        assert!(
            !text.contains("follow a command") && !text.contains("is a scene"),
            "{text}"
        );
    }
}

#[test]
fn gravity_is_a_flag() {
    let dir = scratch("gravity");
    let path = dir.join("sideways.csv");
    let sideways = [
        "run",
        "cube",
        "--steps",
        "10",
        "--dt",
        "0.02",
        "--gravity",
        "3,0,0",
    ];
    let wrote = succeeded(tumble().args(sideways).arg("--trajectory").arg(&path));
    let named = format!("trajectory: steps 0 to 10 written to {}", path.display());
    assert!(String::from_utf8_lossy(&wrote.stderr).contains(&named));
    let rows = std::fs::read_to_string(&path).unwrap();
    // `--trajectory -`: the same rows on standard output, the summary on standard error, and
    // no file named `-`.
    let piped = succeeded(
        tumble()
            .current_dir(&dir)
            .args(sideways)
            .args(["--trajectory", "-"]),
    );
    assert_eq!(String::from_utf8_lossy(&piped.stdout), rows);
    assert!(String::from_utf8_lossy(&piped.stderr).starts_with("scene cube: 8 bodies"));
    assert!(!dir.join("-").exists());
    let _ = std::fs::remove_dir_all(&dir);
    let field = |row: &str, k: usize| row.split(',').nth(k).unwrap().parse::<f64>().unwrap();
    let rows: Vec<&str> = rows.lines().skip(1).collect();
    let (first, last) = (&rows[..8], &rows[rows.len() - 8..]);
    let expected = 3.0 * 0.02 * 0.02 * 10.0 * 11.0 / 2.0;
    for (a, b) in first.iter().zip(last) {
        assert!(
            (field(b, 3) - field(a, 3) - expected).abs() < 1e-12,
            "{a} -> {b}"
        );
        assert_eq!(field(b, 4), field(a, 4), "{a} -> {b}");
    }
}

/// `bench replot` draws the committed runs' plots again from their JSON: one per accuracy
/// scenario and scale family, every tick written to three figures at most (they came as
/// computed, `9.999999999999999e-5`), the legend in its own column right of the plot.
#[test]
fn bench_replot_draws_the_committed_runs_plots_with_readable_ticks() {
    let dir = scratch("replot");
    let bench = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/bench");
    for name in ["accuracy.json", "scale.json"] {
        std::fs::copy(bench.join(name), dir.join(name)).unwrap();
    }
    let out = succeeded(tumble().args(["bench", "replot"]).arg(&dir));
    let wrote = String::from_utf8_lossy(&out.stdout);
    let svgs: Vec<&str> = wrote
        .lines()
        .filter_map(|l| l.strip_prefix("wrote "))
        .collect();
    assert_eq!(svgs.len(), 14 + 4, "{wrote}");
    for svg in svgs {
        let text = std::fs::read_to_string(svg).unwrap();
        let mut legend = 0;
        for label in text.split("<text").skip(1) {
            let (attributes, rest) = label.split_once('>').unwrap();
            let words = rest.split("</text>").next().unwrap().trim();
            if words.parse::<f64>().is_ok() {
                let digits = words.chars().filter(char::is_ascii_digit).count();
                assert!(digits <= 6, "{svg}: tick '{words}'");
            }
            // The legend's entries are the texts anchored at their start.
            if attributes.contains("text-anchor=\"start\"") {
                let x = attributes
                    .split("x=\"")
                    .nth(1)
                    .unwrap()
                    .split('"')
                    .next()
                    .unwrap();
                let x: f64 = x.parse().unwrap();
                assert!(x >= 900.0, "{svg}: legend entry '{words}' inside the plot");
                legend += 1;
            }
        }
        assert!(legend >= 2, "{svg}: {legend} legend entries");
    }
    // A malformed accuracy.json is named, and scale.json's plots are drawn all the same.
    std::fs::write(dir.join("accuracy.json"), "{ \"free_fall\": [").unwrap();
    for svg in std::fs::read_dir(&dir).unwrap().flatten() {
        if svg.path().extension().is_some_and(|e| e == "svg") {
            std::fs::remove_file(svg.path()).unwrap();
        }
    }
    let out = tumble()
        .args(["bench", "replot"])
        .arg(&dir)
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(!out.status.success(), "{stdout}");
    assert!(stderr.contains("accuracy.json"), "{stderr}");
    assert_eq!(stdout.matches("wrote ").count(), 4, "{stdout}");
    let _ = std::fs::remove_dir_all(&dir);
    // A folder that is not there is said to be missing, not to lack the reports.
    let out = tumble()
        .args(["bench", "replot"])
        .arg(&dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("no such folder"),
        "{stderr}"
    );
}
