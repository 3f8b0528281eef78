//! `phalanx train imitation`: behaviour cloning on expert data, then DAgger rounds
//! (`phalanx_rl::imitation::learn`, `docs/imitation.md`), with the progress bars, metrics,
//! curves, atomic checkpoints and exact resume of the other training tasks.
//!
//! The run folder holds:
//! - `config.json`, the run's `ImitationConfig`;
//! - `data-0.bin` (the expert's data), `data-0-K.bin` (the `more_data` sets) and `data-K.bin`
//!   (round K's student rollouts, labelled by the expert), each written atomically once and
//!   read again on resume;
//! - `checkpoint` (learner, optimiser, RNG, counters) every `checkpoint_every` updates and
//!   at the end of every round; `round-K.bin`, the policy at the end of round K;
//! - `validation.jsonl`, one line per round (and, with `validate_every`, one per that many
//!   updates, each snapshot kept as `update-N.bin`): the greedy student on the first
//!   `validation_maps` instances of every Table II row of the validation stream;
//! - `policy.bin`, the snapshot with the best validation figures (success, then loss), and
//!   `metrics.jsonl` and `curves.svg`, the step axis counting updates.

use std::fs;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use burn::tensor::Device;
use phalanx_core::{Instance, PlanMetrics};
use phalanx_env::Task;
use phalanx_eval::Case;
use phalanx_rl::imitation::finetune::{CloningData, Finetune, FinetuneConfig};
use phalanx_rl::imitation::learn::{ImitationConfig, add_to_learner};
use phalanx_rl::imitation::{self, Dataset};
use phalanx_rl::policy_file::network_checksum;
use phalanx_rl::{Learner, Policy, Rollouts, evaluate, metrics};
use serde::{Deserialize, Serialize};

use crate::{plot, util};

/// What `phalanx train imitation` reads from the command line.
pub(crate) struct ImitationArgs {
    pub(crate) config: Option<PathBuf>,
    pub(crate) out: PathBuf,
    pub(crate) resume: bool,
    pub(crate) seed: u64,
    /// Stop after this many updates (the run's total when larger).
    pub(crate) steps: Option<u64>,
    pub(crate) maps: Vec<PathBuf>,
}

/// One snapshot's validation figures (a line of `validation.jsonl`): a round's end, or
/// `validate_every` updates within it.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Validation {
    round: u32,
    updates: u64,
    /// Mean success over the rows.
    success: f64,
    /// Mean over the rows of each row's mean Table II formation loss (solved instances).
    formation_loss: f64,
    /// Per row: label, success, makespan and loss of the solved instances.
    rows: Vec<(String, f64, f64, f64)>,
}

impl Validation {
    /// Whether `self` is better than `other`: higher success, then lower loss.
    fn beats(&self, other: &Validation) -> bool {
        (self.success, -self.formation_loss) > (other.success, -other.formation_loss)
    }
}

/// Runs `phalanx train imitation`.
pub(crate) fn run(args: &ImitationArgs) -> anyhow::Result<ExitCode> {
    let saved = args.out.join("config.json");
    let mut config = match (&args.config, args.resume) {
        (Some(path), _) => read_config(path)?,
        (None, true) if saved.exists() => read_config(&saved)?,
        (None, _) => ImitationConfig::default(),
    };
    if !args.maps.is_empty() {
        config.data.pool.maps.clone_from(&args.maps);
    }
    train(config, args)
}

/// Trains with `config` in `args.out` (`args.config` and `args.maps` are already in it).
pub(crate) fn train(config: ImitationConfig, args: &ImitationArgs) -> anyhow::Result<ExitCode> {
    let dir = &args.out;
    let saved = dir.join("config.json");
    config.check().map_err(|err| anyhow::anyhow!("imitation settings: {err}"))?;
    let device = Device::flex().autodiff();
    let checkpoint = dir.join("checkpoint");
    let fresh = || {
        let (net, counts) = (config.net.clone(), &config.data.agents);
        Learner::new(net, config.learner_config(), counts, args.seed, &device)
    };
    let mut learner = util::learner(args.resume, &checkpoint, fresh, config.init_from.as_deref())?;
    anyhow::ensure!(
        learner.net_config() == &config.net,
        "{}: the checkpoint's network is not the one of the settings",
        checkpoint.display()
    );
    // The student acts, is validated and is saved with the band it learns with.
    learner.set_team_deadband(config.data.env.team_deadband).expect("checked with the settings");
    if !config.data.pool.maps.is_empty() {
        phalanx_env::TrainPool::new(&config.data.pool).context("the training pool")?;
    }
    let validation = validation_instances(&config)?;
    util::written(fs::create_dir_all(dir), dir)?;
    if !args.resume {
        forget_rounds(dir)?;
    }
    let json = serde_json::to_string_pretty(&config).expect("the settings serialise") + "\n";
    util::written(phalanx_io::write_text(&saved, &json), &saved)?;

    let total = config.total_updates().expect("checked");
    anyhow::ensure!(
        learner.counters().updates <= total,
        "{}: the checkpoint is at {} updates, past the {total} of the settings in {}",
        checkpoint.display(),
        learner.counters().updates,
        saved.display()
    );
    let stop = args.steps.map_or(total, |steps| steps.min(total));
    let mut sink = Metrics::open(dir, args.resume.then(|| learner.counters().updates))?;
    let started = Instant::now();
    let mut samples = 0;
    let mut best = read_best(dir)?;
    // Round 0's `more_data` sets, the default data of the fine-tuning's cloning term.
    let mut more = Vec::new();
    // A fine-tuning alone (no cloning update, no round) needs no expert data, unless it
    // clones beside its policy gradient.
    let cloning = config.round_end(config.rounds) > 0 || config.cloning_term();
    for round in (0..=config.rounds).filter(|_| cloning) {
        let end = config.round_end(round);
        let (data, sets) = round_data(&config, dir, round, &learner, !args.resume)?;
        for data in data.iter().chain(&sets) {
            samples += add_to_learner(&mut learner, data)
                .with_context(|| format!("the data of round {round}"))?;
        }
        if round == 0 {
            more = sets;
        }
        let before = learner.counters().updates;
        if before >= end {
            // A round of no updates (DAgger rounds on a student warm-started with `init_from`
            // and `updates` 0): its student is the one it started with, whom the next round
            // rolls out. A finished round has its snapshot already.
            let snapshot = dir.join(format!("round-{round}.bin"));
            if !snapshot.exists() {
                keep_best(&learner, &snapshot, &validation, round, dir, &mut sink, &mut best)?;
            }
            continue;
        }
        let start = if round == 0 { 0 } else { config.round_end(round - 1) };
        if before == start {
            sink.record(metrics::IMITATION_SAMPLES, before, samples as f64)?;
        }
        let step = |learner: &mut Learner| {
            let stats = learner.imitation_update().with_context(|| {
                format!("round {round}: no episode of the data has a step to learn from")
            })?;
            let values = vec![
                (metrics::IMITATION_LOSS, f64::from(stats.loss)),
                (metrics::IMITATION_ACCURACY, f64::from(stats.accuracy)),
                (metrics::GRAD_NORM, f64::from(stats.grad_norm)),
            ];
            let message = format!(
                "| round {round} of {}, loss {:.3}, accuracy {:.3}",
                config.rounds, stats.loss, stats.accuracy
            );
            Ok((values, message))
        };
        let validate = |learner: &Learner, snapshot: &Path, sink: &mut Metrics| {
            keep_best(learner, snapshot, &validation, round, dir, sink, &mut best)
        };
        let span = Span { until: end.min(stop), end, total };
        update_loop(&config, &mut learner, span, dir, &mut sink, step, validate)?;
        let updates = learner.counters().updates;
        if updates < end {
            save(&learner, dir, &mut sink)?;
            break;
        }
        // The end of a round: its policy, its validation, the best so far as policy.bin.
        let snapshot = dir.join(format!("round-{round}.bin"));
        keep_best(&learner, &snapshot, &validation, round, dir, &mut sink, &mut best)?;
        save(&learner, dir, &mut sink)?;
        if updates >= stop {
            break;
        }
    }
    // A fine-tuning goes on up to `stop`; one whose checkpoint is at its end without its
    // network (its `iterations` lowered to the checkpoint's: a fresh run of that length
    // ends there too, every iteration's draws being its own) writes it.
    let updates = learner.counters().updates;
    if let Some(settings) = &config.finetune
        && updates >= config.round_end(config.rounds)
        && (updates < stop || (updates == total && !dir.join(FINETUNED).exists()))
    {
        let run = Finetuning { settings, more: &more, validation: &validation, dir };
        finetune(&config, &run, &mut learner, stop, &mut sink)?;
    }
    let counters = learner.counters();
    let best = match best {
        _ if config.finetune.is_some() && counters.updates == total => {
            "the fine-tuned network (finetune.bin)".to_owned()
        }
        None => "no round finished yet".to_owned(),
        Some(b) => {
            format!("round {} (success {:.3}, loss {:.3})", b.round, b.success, b.formation_loss)
        }
    };
    util::print(&util::table(&[
        ("updates", format!("{} of {total}", counters.updates)),
        ("samples", samples.to_string()),
        ("seconds", format!("{:.1}", started.elapsed().as_secs_f64())),
        ("policy.bin", best),
        ("checkpoint", dir.join("checkpoint").display().to_string()),
        ("curves", dir.join(CURVES).display().to_string()),
    ]))?;
    Ok(ExitCode::SUCCESS)
}

/// The training curves beside the metrics.
const CURVES: &str = "curves.svg";

/// The fine-tuned network, written at the fine-tuning's end.
const FINETUNED: &str = "finetune.bin";

/// The metrics file: JSON lines `{"name", "step", "value"}`, the step counting updates.
struct Metrics {
    out: BufWriter<fs::File>,
    path: PathBuf,
    dir: PathBuf,
}

impl Metrics {
    /// Opens `DIR/metrics.jsonl`: truncated for a fresh run, cut back to the checkpoint's
    /// `updates` and appended to for a resumed one.
    fn open(dir: &Path, resumed_at: Option<u64>) -> anyhow::Result<Metrics> {
        let path = dir.join("metrics.jsonl");
        if let Some(updates) = resumed_at {
            util::cut_metrics(&path, updates)?;
        }
        let file = fs::OpenOptions::new()
            .create(true)
            .append(resumed_at.is_some())
            .write(true)
            .truncate(resumed_at.is_none())
            .open(&path)
            .with_context(|| format!("opening {}", path.display()))?;
        Ok(Metrics { out: BufWriter::new(file), path, dir: dir.to_path_buf() })
    }

    fn record(&mut self, name: &str, step: u64, value: f64) -> anyhow::Result<()> {
        let line = serde_json::json!({ "name": name, "step": step, "value": value });
        util::written(writeln!(self.out, "{line}"), &self.path)
    }

    /// Records an update's `values` and the time since `last`, which it resets.
    fn record_update(
        &mut self,
        updates: u64,
        values: &[(&str, f64)],
        last: &mut Instant,
    ) -> anyhow::Result<()> {
        for &(name, value) in values {
            self.record(name, updates, value)?;
        }
        self.record(metrics::UPDATE_MS, updates, last.elapsed().as_secs_f64() * 1e3)?;
        *last = Instant::now();
        Ok(())
    }

    /// Flushes the metrics and redraws the curves.
    fn flush(&mut self) -> anyhow::Result<()> {
        util::written(self.out.flush(), &self.path)?;
        let svg = self.dir.join(CURVES);
        match plot::imitation_curves(&self.path, &svg) {
            Ok(None) => {}
            Ok(Some(line)) => util::warn(&format!(
                "warning: {}:{line}: skipped lines that are not metrics in the curves",
                self.path.display()
            )),
            Err(err) => util::warn(&format!("warning: no training curves: {err:#}")),
        }
        Ok(())
    }
}

/// Writes the learner's policy to `snapshot`, validates it (a line of `validation.jsonl`, the
/// metrics) and makes it `policy.bin` when it beats `best`.
fn keep_best(
    learner: &Learner,
    snapshot: &Path,
    validation: &[(String, Vec<Instance>)],
    round: u32,
    dir: &Path,
    sink: &mut Metrics,
    best: &mut Option<Validation>,
) -> anyhow::Result<()> {
    let figures = validate_snapshot(learner, snapshot, validation, round, dir, sink)?;
    if best.as_ref().is_none_or(|b| figures.beats(b)) {
        make_policy(snapshot, dir)?;
        *best = Some(figures);
    }
    Ok(())
}

/// Writes the learner's policy to `snapshot` and validates it (a line of `validation.jsonl`,
/// the metrics).
fn validate_snapshot(
    learner: &Learner,
    snapshot: &Path,
    validation: &[(String, Vec<Instance>)],
    round: u32,
    dir: &Path,
    sink: &mut Metrics,
) -> anyhow::Result<Validation> {
    util::written(learner.save_policy(snapshot), snapshot)?;
    let updates = learner.counters().updates;
    let figures = validate(&learner.policy(), validation, round, updates)?;
    sink.record(metrics::VAL_SUCCESS, updates, figures.success)?;
    sink.record(metrics::VAL_FORMATION_LOSS, updates, figures.formation_loss)?;
    append_validation(dir, &figures)?;
    util::warn(&format!(
        "round {round}, {updates} updates: validation success {:.3}, Table II loss {:.3} (mean \
         over the rows)",
        figures.success, figures.formation_loss
    ));
    Ok(figures)
}

/// Copies `snapshot` to `DIR/policy.bin` (atomically).
pub(crate) fn make_policy(snapshot: &Path, dir: &Path) -> anyhow::Result<()> {
    let policy = dir.join("policy.bin");
    let bytes = fs::read(snapshot).with_context(|| format!("reading {}", snapshot.display()))?;
    util::written(phalanx_io::write_bytes(&policy, &bytes), &policy)
}

/// What a fine-tuning runs with.
struct Finetuning<'a> {
    settings: &'a FinetuneConfig,
    /// Round 0's `more_data` sets.
    more: &'a [Dataset],
    validation: &'a [(String, Vec<Instance>)],
    dir: &'a Path,
}

/// The fine-tuning on the meta reward after the rounds ([`Finetune`]), up to `stop` updates:
/// one update per iteration, the iteration being the updates since the rounds' end, so a
/// resumed run goes on where its checkpoint stopped. Its first update starts a fresh Adam at
/// its learning rate. Snapshots every `validate_every` updates are validated (logged, not
/// chosen from); at its end the fine-tuned network, `finetune.bin`, is `policy.bin`. With a
/// cloning term on the `more_data` sets, the learner's buffers are emptied and given those
/// (unless they hold nothing else: [`ImitationConfig::clones_more_only`]).
fn finetune(
    config: &ImitationConfig,
    run: &Finetuning<'_>,
    learner: &mut Learner,
    stop: u64,
    sink: &mut Metrics,
) -> anyhow::Result<()> {
    let Finetuning { settings: finetune, validation, dir, .. } = *run;
    let (start, total) =
        (config.round_end(config.rounds), config.total_updates().expect("checked"));
    if finetune.cloning > 0.0
        && finetune.cloning_data == CloningData::More
        && !config.clones_more_only()
    {
        // The cloning term draws on these only; the same buffers whether the run goes on
        // from its cloning or resumes inside the fine-tuning. (A run that loaded nothing
        // else holds them already, in this order.)
        learner.clear_replays();
        for data in run.more {
            add_to_learner(learner, data).context("the more_data of the cloning term")?;
        }
    }
    let run = Finetune::new(finetune.clone(), config.data.env.clone())
        .map_err(|err| anyhow::anyhow!("imitation settings: {err}"))?;
    if learner.counters().updates == start {
        learner.restart_optimizer(finetune.lr);
    }
    learner.set_team_deadband(run.team_deadband()).expect("checked with the settings");
    let round = config.rounds + 1;
    let step = |learner: &mut Learner| {
        let stats = run.iteration(learner, learner.counters().updates - start);
        let values = vec![
            (metrics::FINETUNE_RETURN, stats.ret),
            (metrics::FINETUNE_SUCCESS, stats.success),
            (metrics::FINETUNE_FORMATION_LOSS, stats.formation_loss),
            (metrics::FINETUNE_STEPS, stats.steps),
            (metrics::POLICY_LOSS, f64::from(stats.policy_loss)),
            (metrics::GRAD_NORM, f64::from(stats.grad_norm)),
        ];
        let values = values
            .into_iter()
            .chain(stats.cloning_loss.map(|it| (metrics::IMITATION_LOSS, f64::from(it))))
            .collect();
        let message = format!(
            "| fine-tuning, {} agents on {}²: success {:.2}, steps {:.1}, loss {:.2}",
            stats.n_agents, stats.side, stats.success, stats.steps, stats.formation_loss
        );
        Ok((values, message))
    };
    let validate = |learner: &Learner, snapshot: &Path, sink: &mut Metrics| {
        validate_snapshot(learner, snapshot, validation, round, dir, sink).map(|_| ())
    };
    update_loop(
        config,
        learner,
        Span { until: stop, end: total, total },
        dir,
        sink,
        step,
        validate,
    )?;
    if learner.counters().updates == total {
        let snapshot = dir.join(FINETUNED);
        validate_snapshot(learner, &snapshot, validation, round, dir, sink)?;
        make_policy(&snapshot, dir)?;
    }
    save(learner, dir, sink)
}

/// The updates a loop makes: up to `until`; its snapshots and checkpoints only before `end`
/// (the one at `end` is the caller's); the bar counts to `total`.
struct Span {
    until: u64,
    end: u64,
    total: u64,
}

/// An update's metrics and the bar's message.
type Step = (Vec<(&'static str, f64)>, String);

/// Updates with `step` over `span`, recording each update's metrics and showing them on the
/// bar; every `validate_every` updates `validate` takes a snapshot `update-N.bin`, every
/// `checkpoint_every` the learner is saved. A snapshot is validated before the checkpoint of
/// the same update: a run stopped between the two resumes before both and validates again.
fn update_loop(
    config: &ImitationConfig,
    learner: &mut Learner,
    span: Span,
    dir: &Path,
    sink: &mut Metrics,
    mut step: impl FnMut(&mut Learner) -> anyhow::Result<Step>,
    mut validate: impl FnMut(&Learner, &Path, &mut Metrics) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let bar = util::rate_bar(span.total, learner.counters().updates, "updates");
    let mut last = Instant::now();
    while learner.counters().updates < span.until {
        let (values, message) = step(learner)?;
        let updates = learner.counters().updates;
        sink.record_update(updates, &values, &mut last)?;
        bar.set_position(updates);
        bar.set_message(message);
        if config.validate_every.is_some_and(|every| updates.is_multiple_of(every))
            && updates < span.end
        {
            let snapshot = dir.join(format!("update-{updates}.bin"));
            bar.suspend(|| validate(learner, &snapshot, sink))?;
        }
        if updates.is_multiple_of(config.checkpoint_every) && updates < span.end {
            save(learner, dir, sink)?;
        }
    }
    bar.finish_and_clear();
    Ok(())
}

/// The metrics flushed, then the checkpoint written atomically.
fn save(learner: &Learner, dir: &Path, sink: &mut Metrics) -> anyhow::Result<()> {
    sink.flush()?;
    let checkpoint = dir.join("checkpoint");
    util::written(learner.save(&checkpoint), &checkpoint)
}

/// Removes what a previous run in `dir` left of its rounds (a fresh run keeps only the
/// expert data, `data-0.bin` and `data-0-K.bin`, which [`round_data`] reads again when it
/// was made with this run's data settings: the same settings make the same expert data).
fn forget_rounds(dir: &Path) -> anyhow::Result<()> {
    let entries = fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))?;
    for entry in entries {
        let path = entry.with_context(|| format!("reading {}", dir.display()))?.path();
        let name = path.file_name().and_then(|it| it.to_str()).unwrap_or_default();
        let stale = name == "validation.jsonl"
            || name.strip_prefix("round-").is_some_and(|it| it.ends_with(".bin"))
            || name.strip_prefix("update-").is_some_and(|it| it.ends_with(".bin"))
            || (name.starts_with("data-") && name.ends_with(".bin") && !is_expert_data(name));
        if stale {
            util::written(fs::remove_file(&path), &path)?;
        }
    }
    Ok(())
}

/// Whether `name` is a run's round-0 expert data file (`data-0.bin`, `data-0-K.bin`): what a
/// fresh run keeps in its folder and reads again when its own settings made it.
pub(crate) fn is_expert_data(name: &str) -> bool {
    name.strip_prefix("data-0")
        .is_some_and(|it| it == ".bin" || (it.starts_with('-') && it.ends_with(".bin")))
}

/// Reads a settings file over the defaults.
fn read_config(path: &Path) -> anyhow::Result<ImitationConfig> {
    let text =
        fs::read_to_string(path).with_context(|| format!("reading config {}", path.display()))?;
    ImitationConfig::from_json(&text)
        .map_err(|err| anyhow::anyhow!("parsing config {}: {err}", path.display()))
}

/// Round `round`'s data: round 0's expert data (`data-0.bin`) and its `more_data` sets
/// (`data-0-K.bin`), or round K's student rollouts labelled by the expert (`data-K.bin`) and
/// no set. A run without cloning updates or rounds, whose fine-tuning's cloning term draws
/// on the `more_data` sets only, needs no `data-0.bin`: none is made or read.
fn round_data(
    config: &ImitationConfig,
    dir: &Path,
    round: u32,
    learner: &Learner,
    fresh: bool,
) -> anyhow::Result<(Option<Dataset>, Vec<Dataset>)> {
    let path = dir.join(format!("data-{round}.bin"));
    if round > 0 {
        let previous = dir.join(format!("round-{}.bin", round - 1));
        let network =
            network_checksum(&previous).with_context(|| format!("the student of round {round}"))?;
        let expected = config.round_data(round, network);
        anyhow::ensure!(
            path.exists() || learner.counters().updates <= config.round_end(round - 1),
            "{}: missing, and the checkpoint is past the round that made it",
            path.display()
        );
        let student = learner.policy();
        let data = data_file(&path, expected, Some(&student), fresh, round)?;
        return Ok((Some(data), Vec::new()));
    }
    let data = if config.clones_more_only() {
        None
    } else {
        Some(data_file(&path, config.data.clone(), None, fresh, round)?)
    };
    let sets = config
        .more_data
        .iter()
        .enumerate()
        .map(|(k, set)| {
            let path = dir.join(format!("data-0-{}.bin", k + 1));
            data_file(&path, set.clone(), None, fresh, round)
        })
        .collect::<anyhow::Result<_>>()?;
    Ok((data, sets))
}

/// A data file: read from `path` when it is there and holds the episodes of `expected`
/// (`DataConfig::same_episodes`: observation settings aside), else generated (the expert's
/// rollouts, or `student`'s labelled by the expert) and written atomically. A file of other
/// settings, or one that cannot be read, is refused in a resumed run and replaced in a
/// `fresh` one.
fn data_file(
    path: &Path,
    expected: imitation::DataConfig,
    student: Option<&Policy>,
    fresh: bool,
    round: u32,
) -> anyhow::Result<Dataset> {
    if path.exists() {
        let read = fs::read(path)
            .map_err(anyhow::Error::from)
            .and_then(|bytes| Dataset::from_bytes(&bytes).map_err(anyhow::Error::from));
        match read {
            // The replay computes the observations with this run's settings.
            Ok(mut data) if data.config.same_episodes(&expected) => {
                data.config = expected;
                return Ok(data);
            }
            // A fresh run makes its own data in place of another run's or a damaged file.
            _ if fresh => {}
            Ok(_) => anyhow::bail!(
                "{}: made with other settings than this run's round {round}",
                path.display()
            ),
            Err(err) => return Err(err.context(format!("reading {}", path.display()))),
        }
    }
    let what = if student.is_none() { "expert episodes" } else { "student episodes" };
    let bar = util::bar(expected.episodes, what);
    let (data, _) = imitation::generate_with(&expected, student, &|n| bar.inc(n))
        .with_context(|| format!("the data of round {round}"))?;
    bar.finish_and_clear();
    util::written(phalanx_io::write_bytes(path, &data.to_bytes()), path)?;
    Ok(data)
}

/// The validation instances: the first `validation_maps` of every Table II row of the
/// stream of `validation_seed` (never the test stream's seed of `phalanx bench`).
fn validation_instances(config: &ImitationConfig) -> anyhow::Result<Vec<(String, Vec<Instance>)>> {
    Case::table2(false)
        .into_iter()
        .filter(|case| config.validation_max_side.is_none_or(|side| case.side <= side))
        .map(|case| {
            let instances = (0..config.validation_maps)
                .map(|index| case.instance(config.validation_seed, index).map(|(it, _)| it))
                .collect::<Result<Vec<_>, _>>()
                .with_context(|| format!("validation instances of {}", case.label))?;
            Ok((case.label, instances))
        })
        .collect()
}

/// The greedy student on the validation instances.
fn validate(
    policy: &Policy,
    rows: &[(String, Vec<Instance>)],
    round: u32,
    updates: u64,
) -> anyhow::Result<Validation> {
    let env = policy.env_config(Task::Meta);
    let mut figures = Vec::new();
    for (label, instances) in rows {
        let mut policy = policy.clone();
        let episodes = evaluate(
            &mut policy,
            Task::Meta,
            &env,
            instances,
            instances.len(),
            Rollouts::default(),
            &mut |_| {},
        )
        .with_context(|| format!("validating on {label}"))?;
        let (mut solved, mut makespan, mut loss) = (0usize, 0.0, 0.0);
        for (episode, instance) in episodes.iter().zip(instances) {
            if episode.success {
                let m = PlanMetrics::of(instance, &episode.plan);
                solved += 1;
                makespan += m.makespan as f64;
                loss += m.formation_loss;
            }
        }
        let per = |x: f64| x / solved.max(1) as f64;
        let success = solved as f64 / instances.len().max(1) as f64;
        figures.push((label.clone(), success, per(makespan), per(loss)));
    }
    let n = figures.len().max(1) as f64;
    Ok(Validation {
        round,
        updates,
        success: figures.iter().map(|it| it.1).sum::<f64>() / n,
        formation_loss: figures.iter().map(|it| it.3).sum::<f64>() / n,
        rows: figures,
    })
}

/// Appends a snapshot's figures to `DIR/validation.jsonl`, dropping lines of as many
/// updates or more (a resumed run repeats what came after its checkpoint).
fn append_validation(dir: &Path, figures: &Validation) -> anyhow::Result<()> {
    let path = dir.join("validation.jsonl");
    let mut kept: Vec<Validation> =
        read_validations(&path)?.into_iter().filter(|it| it.updates < figures.updates).collect();
    kept.push(figures.clone());
    let text: String = kept
        .iter()
        .map(|it| serde_json::to_string(it).expect("figures serialise") + "\n")
        .collect();
    util::written(phalanx_io::write_text(&path, &text), &path)
}

fn read_validations(path: &Path) -> anyhow::Result<Vec<Validation>> {
    let text = match fs::read_to_string(path) {
        Ok(text) => text,
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(err) => return Err(err).with_context(|| format!("reading {}", path.display())),
    };
    text.lines()
        .enumerate()
        .map(|(i, line)| {
            serde_json::from_str(line).with_context(|| format!("{}:{}", path.display(), i + 1))
        })
        .collect()
}

/// The best round so far (of a resumed run).
fn read_best(dir: &Path) -> anyhow::Result<Option<Validation>> {
    let mut best: Option<Validation> = None;
    for it in read_validations(&dir.join("validation.jsonl"))? {
        if best.as_ref().is_none_or(|b| it.beats(b)) {
            best = Some(it);
        }
    }
    Ok(best)
}
