//! Helpers shared by the subcommands: exit codes, reading instances with context, and
//! printing tables and JSON to stdout.

use std::fs;
use std::io::{self, IsTerminal as _, Write};
use std::path::Path;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use phalanx_gen::GenConfig;
use phalanx_io::NamedInstance;

/// The settings of generated instances as flags: one group, flattened into `gen`, `eval`
/// and `sim`, that makes a [`GenConfig`].
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct MapArgs {
    /// Map side (8 to 4096).
    #[arg(long, default_value_t = phalanx_gen::DEFAULT_SIZE)]
    pub(crate) size: u32,
    /// Fraction of blocked cells (0 to 0.4).
    #[arg(long, default_value_t = phalanx_gen::DEFAULT_DENSITY, value_parser = fraction)]
    pub(crate) density: f64,
    /// Agents per instance (default 3; `sim` on an instance file: its first N, default all).
    #[arg(long, value_name = "N")]
    pub(crate) agents: Option<usize>,
    /// Seed of the generator; of a stream of instances (`eval`, `sim`), its base seed.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Field of view side (odd; walls are at most fov / 2 long).
    #[arg(long, default_value_t = phalanx_gen::DEFAULT_FOV)]
    pub(crate) fov: u32,
}

impl MapArgs {
    /// Agents per generated instance.
    pub(crate) fn agents(&self) -> usize {
        self.agents.unwrap_or(phalanx_gen::DEFAULT_AGENTS)
    }

    /// The generator settings.
    pub(crate) fn config(&self) -> GenConfig {
        GenConfig {
            size: self.size,
            density: self.density,
            n_agents: self.agents(),
            seed: self.seed,
            fov: self.fov,
        }
    }
}

/// The plan is invalid (`validate`).
pub(crate) const EXIT_INVALID: u8 = 1;
/// Bad input: unreadable or malformed files, bad flags.
pub(crate) const EXIT_BAD_INPUT: u8 = 2;
/// A failure while working: an output (plan, instance, checkpoint, metrics, report) that
/// cannot be written.
pub(crate) const EXIT_RUNTIME: u8 = 3;

/// An incomplete planner (prioritised A*) found no plan: the instance may still be solvable.
pub(crate) const EXIT_INCOMPLETE: u8 = 4;

/// A peer of a decentralised run is gone: the world stopped answering an agent, or the
/// others never joined.
pub(crate) const EXIT_PEER_GONE: u8 = 6;

/// Marks an error as a peer of a decentralised run gone (exit [`EXIT_PEER_GONE`]).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct PeerGone(pub(crate) String);

/// Marks an error as a failed write of an output (exit [`EXIT_RUNTIME`], not bad input).
#[derive(Debug, thiserror::Error)]
#[error("writing {0}")]
pub(crate) struct WriteFailed(pub(crate) String);

/// Marks the error of writing `what` as a [`WriteFailed`].
pub(crate) fn written<T, E>(result: Result<T, E>, what: &Path) -> anyhow::Result<T>
where
    E: Into<anyhow::Error>,
{
    result.map_err(|err| err.into().context(WriteFailed(what.display().to_string())))
}

/// The exit code of a failed command: [`EXIT_RUNTIME`] for a failed write,
/// [`EXIT_PEER_GONE`] for a decentralised run's missing peer, else [`EXIT_BAD_INPUT`].
pub(crate) fn exit_code(err: &anyhow::Error) -> u8 {
    if err.downcast_ref::<WriteFailed>().is_some() {
        EXIT_RUNTIME
    } else if err.downcast_ref::<PeerGone>().is_some() {
        EXIT_PEER_GONE
    } else {
        EXIT_BAD_INPUT
    }
}

/// A flag value that is a finite number of at least 0.
pub(crate) fn non_negative(text: &str) -> Result<f64, String> {
    number(text)
        .and_then(|v| if v >= 0.0 { Ok(v) } else { Err(format!("{} is negative", shown(v))) })
}

/// A flag value that is a finite number above 0.
pub(crate) fn positive(text: &str) -> Result<f64, String> {
    number(text)
        .and_then(|v| if v > 0.0 { Ok(v) } else { Err(format!("{} is not above 0", shown(v))) })
}

/// A flag value that is a probability or a fraction: a number in `[0, 1]`.
pub(crate) fn fraction(text: &str) -> Result<f64, String> {
    number(text).and_then(|v| {
        if (0.0..=1.0).contains(&v) { Ok(v) } else { Err(format!("{} is not in [0, 1]", shown(v))) }
    })
}

/// `--team-deadband`: a finite number of cells, 0 or more (the environment's own check).
pub(crate) fn team_deadband(text: &str) -> Result<f64, String> {
    let cells = number(text)?;
    phalanx_env::check_team_deadband(cells).map(|()| cells).map_err(|err| err.to_string())
}

/// The longest duration a flag in seconds accepts (`--time-limit`, `--join-timeout`,
/// `--silence`): about eleven days.
pub(crate) const MAX_SECONDS: f64 = 1e6;

/// A duration flag in seconds: a finite number above 0 and at most [`MAX_SECONDS`]; every
/// duration flag reads through this one parser, so none reaches `Duration` out of range.
pub(crate) fn seconds(text: &str) -> Result<f64, String> {
    positive(text).and_then(|v| {
        if v <= MAX_SECONDS {
            Ok(v)
        } else {
            Err(format!("{} s is longer than the longest duration, {MAX_SECONDS:e} s", shown(v)))
        }
    })
}

/// The duration of `seconds`, a value [`seconds`] accepted.
pub(crate) fn duration(seconds: f64) -> Duration {
    Duration::try_from_secs_f64(seconds).unwrap_or(Duration::MAX)
}

/// A flag value in `[lo, hi]` (a finite number).
pub(crate) fn within(text: &str, lo: f64, hi: f64) -> Result<f64, String> {
    number(text).and_then(|v| {
        if (lo..=hi).contains(&v) {
            Ok(v)
        } else {
            Err(format!("{} is not in [{lo}, {hi}]", shown(v)))
        }
    })
}

/// A Zenoh endpoint to connect to (`--connect`): as [`listen_endpoint`], the port not 0.
/// Checked here so that an agent told to connect to `tcp/999.1.1.1:1` says so at once
/// instead of waiting for a world that cannot be reached.
#[cfg(feature = "processes")]
pub(crate) fn connect_endpoint(text: &str) -> Result<String, String> {
    endpoint(text, 1)
}

/// A Zenoh endpoint to listen on (`--listen`): `PROTOCOL/ADDRESS`; for `tcp`, `udp`, `tls`
/// and `quic` the address is `HOST:PORT` with a port from 0 (any free one) to 65535 and,
/// where the host is written as an IP address, a valid one.
#[cfg(feature = "processes")]
pub(crate) fn listen_endpoint(text: &str) -> Result<String, String> {
    endpoint(text, 0)
}

/// An endpoint whose port is at least `min_port`.
#[cfg(feature = "processes")]
fn endpoint(text: &str, min_port: u16) -> Result<String, String> {
    let Some((protocol, address)) = text.split_once('/') else {
        return Err(format!(
            "{text:?} is not an endpoint (PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447)"
        ));
    };
    if !matches!(protocol, "tcp" | "udp" | "tls" | "quic") {
        return Ok(text.to_owned());
    }
    let address = address.split_once('#').map_or(address, |(it, _)| it);
    let Some((host, port)) = address.rsplit_once(':') else {
        return Err(format!("{text:?}: the address {address:?} has no port (HOST:PORT)"));
    };
    match port.parse::<u16>() {
        Ok(port) if port >= min_port => {}
        _ => {
            return Err(format!(
                "{text:?}: the port {port:?} is not a number from {min_port} to 65535"
            ));
        }
    }
    let ip_like = !host.is_empty() && host.chars().all(|c| c.is_ascii_digit() || c == '.');
    let bad_ip = if let Some(v6) = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        v6.parse::<std::net::Ipv6Addr>().is_err()
    } else {
        host.is_empty() || (ip_like && host.parse::<std::net::Ipv4Addr>().is_err())
    };
    if bad_ip {
        return Err(format!("{text:?}: the host {host:?} is not a valid address"));
    }
    Ok(text.to_owned())
}

/// `v` as a message shows it: in scientific notation when very large or very small, so that
/// 1e300 is not printed with 300 digits.
pub(crate) fn shown(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e6).contains(&v.abs()) { format!("{v:e}") } else { format!("{v}") }
}

/// A finite number.
fn number(text: &str) -> Result<f64, String> {
    let v: f64 = text.trim().parse().map_err(|_| format!("{text:?} is not a number"))?;
    if v.is_finite() { Ok(v) } else { Err(format!("{text} is not a finite number")) }
}

/// Reads an instance, format by extension (`.yaml`/`.yml` or `.scen` with its map);
/// `n_agents` takes the first entries of a scenario.
pub(crate) fn read_instance(path: &Path, n_agents: Option<usize>) -> anyhow::Result<NamedInstance> {
    phalanx_io::read_instance(path, n_agents).context("reading the instance")
}

/// Writes `text` to stdout; a closed pipe is not an error.
pub(crate) fn print(text: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(err) if err.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(err).context("writing to stdout")
        }
        _ => Ok(()),
    }
}

/// Writes one line to stderr (diagnostics that are not errors of the program).
pub(crate) fn warn(line: &str) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// Prints one JSON object on one line.
pub(crate) fn print_json(value: &serde_json::Value) -> anyhow::Result<()> {
    print(&format!("{value}\n"))
}

/// Key–value rows with the keys padded to one width.
pub(crate) fn table(rows: &[(&str, String)]) -> String {
    let width = rows.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
    rows.iter().map(|(k, v)| format!("{k:<width$}  {v}\n")).collect()
}

/// Rows of cells with each column padded to its widest cell (the last is not padded).
pub(crate) fn columns(rows: &[Vec<String>]) -> String {
    let n_cols = rows.iter().map(Vec::len).max().unwrap_or(0);
    let widths: Vec<usize> = (0..n_cols)
        .map(|c| rows.iter().filter_map(|r| r.get(c)).map(String::len).max().unwrap_or(0))
        .collect();
    let mut res = String::new();
    for row in rows {
        let mut line = String::new();
        for (c, cell) in row.iter().enumerate() {
            if c + 1 == row.len() {
                line.push_str(cell);
            } else {
                line.push_str(&format!("{cell:<w$}  ", w = widths[c]));
            }
        }
        res.push_str(line.trim_end());
        res.push('\n');
    }
    res
}

/// Cuts the metrics of a resumed run back to its checkpoint at `env_steps`: the metrics are
/// flushed before every checkpoint, so the file holds every line up to it, and may hold more
/// (lines flushed after it, the last one perhaps half-written when the run was killed). The
/// first line that is incomplete, not a record, or of a step after the checkpoint, and all
/// after it, go; the resumed run writes them again, exactly (every record after a checkpoint
/// has a later step: a chunk ends with its last step's updates).
pub(crate) fn cut_metrics(path: &Path, env_steps: u64) -> anyhow::Result<()> {
    let text = match fs::read(path) {
        Ok(text) => text,
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(err) => return Err(err).with_context(|| format!("reading {}", path.display())),
    };
    let mut keep = 0;
    for line in text.split_inclusive(|&b| b == b'\n') {
        let step = line
            .strip_suffix(b"\n")
            .and_then(|line| serde_json::from_slice::<serde_json::Value>(line).ok())
            .and_then(|record| record.get("step").and_then(serde_json::Value::as_u64));
        match step {
            Some(step) if step <= env_steps => keep += line.len(),
            _ => break,
        }
    }
    if keep < text.len() {
        let file = fs::OpenOptions::new()
            .write(true)
            .open(path)
            .with_context(|| format!("opening {}", path.display()))?;
        written(file.set_len(keep as u64), path)?;
    }
    Ok(())
}

/// How often a bar writes its line when stderr is not a terminal.
const LOG_EVERY: Duration = Duration::from_secs(60);

/// A bar's draw target off a terminal (a log file, `nohup`, CI): its line as a plain line of
/// its own at most once every [`LOG_EVERY`], the first after one interval, so that long work
/// shows its progress in a log and short work writes nothing there.
struct LogLines {
    every: Duration,
    /// When the last line was written, and where lines go (stderr).
    state: Mutex<(Instant, Box<dyn Write + Send>)>,
}

impl std::fmt::Debug for LogLines {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LogLines").field("every", &self.every).finish_non_exhaustive()
    }
}

impl LogLines {
    fn new(every: Duration, out: Box<dyn Write + Send>) -> LogLines {
        LogLines { every, state: Mutex::new((Instant::now(), out)) }
    }

    fn write(&self, line: &str) -> io::Result<()> {
        let line = line.trim();
        let mut state = self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let (last, out) = &mut *state;
        if line.is_empty() || last.elapsed() < self.every {
            return Ok(());
        }
        *last = Instant::now();
        writeln!(out, "{line}")
    }
}

impl indicatif::TermLike for LogLines {
    fn width(&self) -> u16 {
        100
    }
    fn move_cursor_up(&self, _: usize) -> io::Result<()> {
        Ok(())
    }
    fn move_cursor_down(&self, _: usize) -> io::Result<()> {
        Ok(())
    }
    fn move_cursor_right(&self, _: usize) -> io::Result<()> {
        Ok(())
    }
    fn move_cursor_left(&self, _: usize) -> io::Result<()> {
        Ok(())
    }
    fn write_line(&self, line: &str) -> io::Result<()> {
        self.write(line)
    }
    fn write_str(&self, line: &str) -> io::Result<()> {
        self.write(line)
    }
    fn clear_line(&self) -> io::Result<()> {
        Ok(())
    }
    fn flush(&self) -> io::Result<()> {
        Ok(())
    }
}

/// A progress bar of `len` drawn with `template` (indicatif's keys, `{rate}` the rate per
/// second with one decimal, `{eta}` as [`mean_eta`] computes it): on stderr when it is a
/// terminal, else a plain line a minute ([`LogLines`]).
pub(crate) fn styled_bar(len: u64, template: &str) -> indicatif::ProgressBar {
    styled_bar_from(len, 0, template)
}

/// The time left at the mean rate since the bar started at `start`: `-` before the first step.
/// indicatif's own estimate weighs the last seconds; where one step takes longer than that
/// window (a student's episode relabelled by CBS, a 1024² benchmark run), it decays towards
/// no progress at all between steps and showed hours for minutes of work.
fn mean_eta(state: &indicatif::ProgressState, start: u64) -> Option<Duration> {
    time_left(state.elapsed(), start, state.pos(), state.len()?)
}

/// `elapsed` for the steps from `start` to `pos`, so much again for each of the steps to `len`.
fn time_left(elapsed: Duration, start: u64, pos: u64, len: u64) -> Option<Duration> {
    let done = pos.saturating_sub(start);
    (done > 0).then(|| elapsed.mul_f64(len.saturating_sub(pos) as f64 / done as f64))
}

/// [`styled_bar`] standing at `start` (a resumed run's), its ETA counting from there.
fn styled_bar_from(len: u64, start: u64, template: &str) -> indicatif::ProgressBar {
    let target = if io::stderr().is_terminal() {
        indicatif::ProgressDrawTarget::stderr()
    } else {
        let lines = LogLines::new(LOG_EVERY, Box::new(io::stderr()));
        indicatif::ProgressDrawTarget::term_like_with_hz(Box::new(lines), 1)
    };
    let style = indicatif::ProgressStyle::with_template(template)
        .expect("a valid template")
        .with_key("rate", |state: &indicatif::ProgressState, out: &mut dyn std::fmt::Write| {
            let _ = write!(out, "{:.1}", state.per_sec());
        })
        .with_key("eta", move |state: &indicatif::ProgressState, out: &mut dyn std::fmt::Write| {
            let _ = match mean_eta(state, start) {
                Some(eta) => write!(out, "{:#}", indicatif::HumanDuration(eta)),
                None => write!(out, "-"),
            };
        })
        .progress_chars("=> ");
    let bar = indicatif::ProgressBar::with_draw_target(Some(len), target).with_style(style);
    bar.set_position(start);
    bar
}

/// A progress bar of `len` `unit`s standing at `at`, with the rate per second and the ETA,
/// ticking twice a second (the training runs' bar).
pub(crate) fn rate_bar(len: u64, at: u64, unit: &str) -> indicatif::ProgressBar {
    let bar = styled_bar_from(
        len,
        at,
        &format!(
            "{{elapsed_precise}} [{{bar:30}}] {{pos}}/{{len}} {unit}, {{rate}} {unit}/s, eta {{eta}} {{msg}}"
        ),
    );
    bar.reset_eta();
    bar.enable_steady_tick(Duration::from_millis(500));
    bar
}

/// A progress bar of `len` `what` with the ETA.
pub(crate) fn bar(len: u64, what: &str) -> indicatif::ProgressBar {
    styled_bar(
        len,
        &format!("{{elapsed_precise}} [{{bar:30}}] {{pos}}/{{len}} {what}, eta {{eta}}"),
    )
}

/// The learner of a training run: restored from `checkpoint` when `resume`, else `fresh()`
/// warm-started from `init_from` when given (a checkpoint or policy file).
pub(crate) fn learner(
    resume: bool,
    checkpoint: &Path,
    fresh: impl FnOnce() -> phalanx_rl::Learner,
    init_from: Option<&Path>,
) -> anyhow::Result<phalanx_rl::Learner> {
    if resume {
        // A run stopped before its first checkpoint has none; starting it again reuses what
        // it finished (an imitation run's expert data).
        anyhow::ensure!(
            checkpoint.exists(),
            "resuming: {} does not exist: the run stopped before its first checkpoint, or --out \
             names another folder; start it again without --resume",
            checkpoint.display()
        );
        let device = burn::tensor::Device::flex().autodiff();
        return phalanx_rl::Learner::load(checkpoint, &device).context("resuming");
    }
    let mut learner = fresh();
    if let Some(path) = init_from {
        learner.init_from(path).context("warm start (init_from)")?;
    }
    Ok(learner)
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use indicatif::TermLike as _;

    use super::*;

    /// A writer whose bytes the test reads back.
    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);

    impl Write for Shared {
        fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(bytes);
            Ok(bytes.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn the_eta_is_the_time_left_at_the_mean_rate_since_the_bar_started() {
        let minute = Duration::from_secs(60);
        // 66 of 300 slow episodes in 109 s: about 6 minutes left, not hours.
        let left = time_left(Duration::from_secs(109), 0, 66, 300).unwrap();
        assert_eq!(left.as_secs(), 386);
        // A resumed run counts only its own steps.
        assert_eq!(time_left(minute, 100, 110, 200), Some(minute * 9));
        assert_eq!(time_left(minute, 100, 100, 200), None, "no step yet: no estimate");
        assert_eq!(time_left(minute, 0, 10, 10), Some(Duration::ZERO));
    }

    #[test]
    fn off_a_terminal_a_bar_writes_plain_lines_at_most_once_an_interval() {
        let out = Shared::default();
        let text = || String::from_utf8(out.0.lock().unwrap().clone()).unwrap();
        let lines = LogLines::new(Duration::ZERO, Box::new(out.clone()));
        lines.clear_line().unwrap();
        lines.write_str("  00:01:00 [=>  ] 3/10 episodes, eta 2m  ").unwrap();
        lines.write_line("").unwrap();
        lines.write_line("00:02:00 [==> ] 6/10 episodes, eta 1m").unwrap();
        assert_eq!(
            text(),
            "00:01:00 [=>  ] 3/10 episodes, eta 2m\n00:02:00 [==> ] 6/10 episodes, eta 1m\n"
        );

        let out = Shared::default();
        let lines = LogLines::new(Duration::from_secs(3600), Box::new(out.clone()));
        lines.write_str("00:00:01 [    ] 0/10 episodes").unwrap();
        assert!(out.0.lock().unwrap().is_empty(), "nothing before the first interval");
    }
}
