//! The help of every subcommand cites the papers, not internal document numbers: no "seed"
//! (a user has no such documents; docs/theory.md lists the papers).

use super::run_balloon;

/// The subcommands the help text `help` lists under `Commands:` (without `help`).
fn subcommands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_string)
        .collect()
}

#[test]
fn no_help_text_says_seed() {
    let mut queue: Vec<Vec<String>> = vec![Vec::new()];
    let mut seen = 0;
    while let Some(path) = queue.pop() {
        for flag in ["--help", "-h"] {
            let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
            args.push(flag);
            let out = run_balloon(&args);
            assert!(out.status.success(), "balloon {}", args.join(" "));
            let text = String::from_utf8_lossy(&out.stdout);
            for (i, line) in text.lines().enumerate() {
                assert!(
                    !line.to_lowercase().contains("seed"),
                    "`balloon {}` line {}: {line}",
                    args.join(" "),
                    i + 1
                );
            }
            if flag == "--help" {
                for c in subcommands(&text) {
                    let mut p = path.clone();
                    p.push(c);
                    queue.push(p);
                }
            }
        }
        seen += 1;
    }
    // balloon, mesh, mesh info, inflate, connect, volumetric, two-layer, run, view at least.
    assert!(seen >= 9, "only {seen} help texts found");
}
