//! `nusselt bench --doc`: the figure tables in README.md and docs/*.md, written from the
//! committed CSVs under `bench/` (no benchmark runs; CSV to markdown only), so that every
//! quoted benchmark figure has one source. `--check` writes nothing and fails where a
//! document differs from what the CSVs give (tests/bench_doc.rs runs it).
//!
//! A generated region is the lines between `<!-- bench:table NAME -->` and
//! `<!-- /bench:table -->`; NAME picks the table ([`TABLES`]). Each table opens with the
//! command that wrote its CSV and the date, from the CSV's leading `# command:` and
//! `# date:` lines (written by the bench since these were added; the older CSVs had them
//! added by hand from their commits).
//!
//! The CSVs are written without quoting, and some labels hold ", " (e.g. `shooting, no
//! ambient`): a field that starts with a space is read as the continuation of the one
//! before it, and a row must then have as many fields as the header.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use nusselt_core::solver::DEFAULT_LINK_TOLERANCE;

use super::bench_images::first_time_below;

/// Writes one table from the CSVs in the folder it is given.
type Table = fn(&Path) -> Result<String>;

/// The tables a region can name, and the function that writes each from `bench/`.
const TABLES: [(&str, Table); 12] = [
    ("convergence", convergence),
    ("ambient", ambient),
    ("targets", targets),
    ("targets-summary", targets_summary),
    ("cornell-image", cornell_image),
    ("cornell-image-summary", cornell_image_summary),
    ("meshing", meshing),
    ("hierarchical", hierarchical),
    ("large", large),
    ("specular", specular),
    ("specular-summary", specular_summary),
    ("live-edits", live_edits),
];

const OPEN: &str = "<!-- bench:table ";
const CLOSE: &str = "<!-- /bench:table -->";

/// Rewrites (or with `check`, compares) every generated region in `root`'s README.md and
/// docs/*.md from the CSVs in `csv_dir`.
pub fn run(csv_dir: &Path, root: &Path, check: bool) -> Result<()> {
    let mut stale = Vec::new();
    let mut regions = 0;
    for doc in documents(root)? {
        let text =
            std::fs::read_to_string(&doc).with_context(|| format!("reading {}", doc.display()))?;
        let (new, count) = rewrite(&text, &doc, csv_dir)?;
        regions += count;
        if new != text {
            if check {
                stale.push(doc.display().to_string());
            } else {
                std::fs::write(&doc, new).with_context(|| format!("writing {}", doc.display()))?;
                eprintln!("wrote {}", doc.display());
            }
        }
    }
    if !stale.is_empty() {
        bail!(
            "figures differ from the CSVs in {}: run `nusselt bench --doc`",
            stale.join(", ")
        );
    }
    eprintln!("{regions} generated regions checked");
    Ok(())
}

/// README.md and docs/*.md under `root`, sorted.
fn documents(root: &Path) -> Result<Vec<PathBuf>> {
    let readme = root.join("README.md");
    if !readme.is_file() {
        bail!(
            "{} not found: run `nusselt bench --doc` from the repository root",
            readme.display()
        );
    }
    let mut docs = vec![readme];
    let dir = root.join("docs");
    let mut more: Vec<PathBuf> = std::fs::read_dir(&dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    more.sort();
    docs.extend(more);
    Ok(docs)
}

/// `text` with each region's lines replaced by its table (a blank line either side), and
/// the number of regions.
fn rewrite(text: &str, doc: &Path, csv_dir: &Path) -> Result<(String, usize)> {
    let mut out = String::with_capacity(text.len());
    let mut lines = text.split_inclusive('\n').enumerate();
    let mut count = 0;
    while let Some((i, line)) = lines.next() {
        out.push_str(line);
        let Some(name) = line
            .trim()
            .strip_prefix(OPEN)
            .and_then(|rest| rest.strip_suffix("-->"))
            .map(str::trim)
        else {
            continue;
        };
        let at = || format!("{}:{}", doc.display(), i + 1);
        let Some((_, table)) = TABLES.iter().find(|(n, _)| *n == name) else {
            bail!("{}: no bench table named `{name}`", at());
        };
        let body = table(csv_dir).with_context(at)?;
        let Some((_, close)) = lines.by_ref().find(|(_, l)| l.trim() == CLOSE) else {
            bail!("{}: `{OPEN}{name} -->` has no `{CLOSE}`", at());
        };
        write!(out, "\n{body}\n")?;
        out.push_str(close);
        count += 1;
    }
    Ok((out, count))
}

/// One CSV under `bench/`: its provenance, header and rows.
struct Csv {
    file: String,
    command: String,
    date: String,
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Csv {
    fn load(dir: &Path, name: &str) -> Result<Csv> {
        let path = dir.join(format!("{name}.csv"));
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        Csv::parse(&format!("bench/{name}.csv"), &text)
    }

    fn parse(file: &str, text: &str) -> Result<Csv> {
        let (mut command, mut date) = (None, None);
        let mut header: Option<Vec<String>> = None;
        let mut rows = Vec::new();
        for (i, line) in text.lines().enumerate() {
            if let Some(comment) = line.strip_prefix('#') {
                let comment = comment.trim();
                if let Some(c) = comment.strip_prefix("command:") {
                    command = Some(c.trim().to_string());
                } else if let Some(d) = comment.strip_prefix("date:") {
                    date = Some(d.trim().to_string());
                }
                continue;
            }
            if line.trim().is_empty() {
                continue;
            }
            let fields = split_fields(line);
            match &header {
                None => header = Some(fields),
                Some(h) if h.len() != fields.len() => bail!(
                    "{file}:{}: {} fields where the header has {}",
                    i + 1,
                    fields.len(),
                    h.len()
                ),
                Some(_) => rows.push(fields),
            }
        }
        let Some(header) = header else {
            bail!("{file}: no header row");
        };
        let (Some(command), Some(date)) = (command, date) else {
            bail!("{file}: no `# command:` and `# date:` lines");
        };
        Ok(Csv {
            file: file.to_string(),
            command,
            date,
            header,
            rows,
        })
    }

    /// The line each table opens with: where its figures come from.
    fn source(&self) -> String {
        format!(
            "Generated by `nusselt bench --doc` from `{}`, written by `{}` on {}.\n",
            self.file, self.command, self.date
        )
    }

    fn column(&self, name: &str) -> Result<usize> {
        self.header
            .iter()
            .position(|h| h == name)
            .with_context(|| format!("{}: no column `{name}`", self.file))
    }

    /// The rows as maps from column name, in file order.
    fn records(&self) -> impl Iterator<Item = Record<'_>> {
        self.rows
            .iter()
            .map(move |fields| Record { csv: self, fields })
    }
}

/// Splits a row at commas; a field that starts with a space continues the previous one.
fn split_fields(line: &str) -> Vec<String> {
    let mut fields: Vec<String> = Vec::new();
    for part in line.split(',') {
        match fields.last_mut() {
            Some(last) if part.starts_with(' ') => {
                last.push(',');
                last.push_str(part);
            }
            _ => fields.push(part.to_string()),
        }
    }
    fields
}

struct Record<'a> {
    csv: &'a Csv,
    fields: &'a [String],
}

impl<'a> Record<'a> {
    fn text(&self, column: &str) -> Result<&'a str> {
        Ok(&self.fields[self.csv.column(column)?])
    }

    fn num(&self, column: &str) -> Result<f64> {
        let text = self.text(column)?;
        text.parse()
            .with_context(|| format!("{}: `{text}` in `{column}` is not a number", self.csv.file))
    }

    /// `None` for an empty field or `-`.
    fn opt(&self, column: &str) -> Result<Option<f64>> {
        match self.text(column)? {
            "" | "-" => Ok(None),
            _ => self.num(column).map(Some),
        }
    }
}

/// `1234567` as `1,234,567`.
fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Three significant figures for times from 0.1 s to 1,000 s.
fn secs3(x: f64) -> String {
    let decimals = if x < 1.0 {
        3
    } else if x < 10.0 {
        2
    } else if x < 100.0 {
        1
    } else {
        0
    };
    format!("{x:.decimals$}")
}

fn or_dash(x: Option<String>) -> String {
    x.unwrap_or_else(|| "–".into())
}

/// The path tracer's time to an error `limit`: the first measured `(seconds, error)` at or
/// below it, else extrapolated from the last (error ∝ 1/√spp, time ∝ spp).
fn path_tracer_time(runs: &[(f64, f64)], limit: f64) -> Option<(f64, bool)> {
    if let Some(t) = first_time_below(runs.iter().copied(), limit) {
        return Some((t, false));
    }
    runs.last().map(|(t, e)| (t * (e / limit).powi(2), true))
}

/// `convergence.csv`: each solver's last logged row per scene. The times to 1 % and 0.1 %
/// are read from the logged rows (one each time the residual falls by 20 %), so they are
/// the first logged time from which the error stays below, not the exact step.
fn convergence(dir: &Path) -> Result<String> {
    let csv = Csv::load(dir, "convergence")?;
    let mut out = csv.source();
    out.push_str("\n| scene | solver | elements | patches | steps | seconds | residual | error | s to 1 % | s to 0.1 % | matrix MB |\n");
    out.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    let records: Vec<Record> = csv.records().collect();
    let mut start = 0;
    while start < records.len() {
        let key = (
            records[start].text("scene")?,
            records[start].text("solver")?,
        );
        let mut end = start;
        while end < records.len()
            && (records[end].text("scene")?, records[end].text("solver")?) == key
        {
            end += 1;
        }
        let run = &records[start..end];
        let mut points = Vec::new();
        for r in run {
            if let Some(e) = r.opt("error")? {
                points.push((r.num("seconds")?, e));
            }
        }
        let to = |limit| {
            (points.len() == run.len())
                .then(|| first_time_below(points.iter().copied(), limit))
                .flatten()
                .map(|t| format!("{t:.3}"))
        };
        let last = &run[run.len() - 1];
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.3} | {:.1e} | {} | {} | {} | {:.1} |",
            key.0,
            key.1,
            last.text("elements")?,
            last.text("patches")?,
            last.text("step")?,
            last.num("seconds")?,
            last.num("residual")?,
            or_dash(last.opt("error")?.map(|e| format!("{e:.1e}"))),
            or_dash(to(1e-2)),
            or_dash(to(1e-3)),
            last.num("matrix_mb")?,
        )?;
        start = end;
    }
    Ok(out)
}

/// `ambient.csv`: the display correction in the unlit room, as `bench --only tworooms`
/// prints it.
fn ambient(dir: &Path) -> Result<String> {
    let csv = Csv::load(dir, "ambient")?;
    let mut out = csv.source();
    out.push_str("\n| tworooms (unlit room) | after 1 s: residual | image error | after 2 s: image error | s to 10 % |\n");
    out.push_str("|---|---:|---:|---:|---:|\n");
    let mut labels: Vec<&str> = Vec::new();
    for r in csv.records() {
        let label = r.text("variant")?;
        if !labels.contains(&label) {
            labels.push(label);
        }
    }
    for label in labels {
        let mut run = Vec::new();
        for r in csv.records() {
            if r.text("variant")? == label {
                run.push((r.num("seconds")?, r.num("residual")?, r.num("image_error")?));
            }
        }
        let at = |limit: f64| run.iter().rev().find(|r| r.0 <= limit);
        let to_10 = first_time_below(run.iter().map(|r| (r.0, r.2)), 0.1);
        writeln!(
            out,
            "| {label} | {} | {} | {} | {} |",
            or_dash(at(1.0).map(|r| format!("{:.3}", r.1))),
            or_dash(at(1.0).map(|r| format!("{:.3}", r.2))),
            or_dash(at(2.0).map(|r| format!("{:.3}", r.2))),
            or_dash(to_10.map(|t| format!("{t:.2}"))),
        )?;
    }
    Ok(out)
}

/// One radiosity target of `targets.csv` and the path tracer's time to its error.
struct Target {
    flags: String,
    median: f64,
    min: f64,
    max: f64,
    error: f64,
    target_error: f64,
    target_s: String,
    met: bool,
    path_tracer: Option<(f64, bool)>,
}

/// `targets.csv`'s path tracer runs as `(spp, seconds, error)`.
type Traced = Vec<(String, f64, f64)>;

/// `targets.csv`: the path tracer's runs, and the radiosity targets.
fn load_targets(dir: &Path) -> Result<(Csv, Traced, Vec<Target>)> {
    let csv = Csv::load(dir, "targets")?;
    let mut traced = Vec::new();
    for r in csv.records() {
        if r.text("kind")? == "pathtracer" {
            let spp = r.text("flags")?.trim_start_matches("--spp ").to_string();
            traced.push((spp, r.num("median_s")?, r.num("error")?));
        }
    }
    let runs: Vec<(f64, f64)> = traced.iter().map(|(_, t, e)| (*t, *e)).collect();
    let mut targets = Vec::new();
    for r in csv.records() {
        if r.text("kind")? != "radiosity" {
            continue;
        }
        let (median, error) = (r.num("median_s")?, r.num("error")?);
        let (target_error, target_seconds) = (r.num("target_error")?, r.num("target_s")?);
        targets.push(Target {
            flags: r.text("flags")?.to_string(),
            median,
            min: r.num("min_s")?,
            max: r.num("max_s")?,
            error,
            target_error,
            target_s: r.text("target_s")?.to_string(),
            met: error <= target_error && median <= target_seconds,
            path_tracer: path_tracer_time(&runs, target_error),
        });
    }
    Ok((csv, traced, targets))
}

fn path_tracer_phrase(time: Option<(f64, bool)>) -> String {
    match time {
        Some((t, false)) => format!("{} s", secs3(t)),
        Some((t, true)) => format!("~{t:.0} s (extrapolated)"),
        None => "–".into(),
    }
}

/// `targets.csv`: the Cornell box's whole-process time to each target, and the path
/// tracer's.
fn targets(dir: &Path) -> Result<String> {
    let (csv, traced, targets) = load_targets(dir)?;
    let mut out = csv.source();
    out.push_str("\n| target | flags (after `render --builtin cornell`) | median s (min–max) | error | met | path tracer s |\n");
    out.push_str("|---|---|---:|---:|---|---:|\n");
    for t in &targets {
        writeln!(
            out,
            "| {:.0} % in {} s | `{}` | {} ({}–{}) | {:.2} % | {} | {} |",
            t.target_error * 100.0,
            t.target_s,
            t.flags,
            secs3(t.median),
            secs3(t.min),
            secs3(t.max),
            t.error * 100.0,
            if t.met { "yes" } else { "no" },
            path_tracer_phrase(t.path_tracer),
        )?;
    }
    let runs: Vec<String> = traced
        .iter()
        .map(|(spp, t, e)| format!("{spp} spp {:.1} % in {} s", e * 100.0, secs3(*t)))
        .collect();
    writeln!(
        out,
        "\nThe path tracer (`nusselt reference --spp N`, one run each): {}; past its last \
         count its time is extrapolated (error ∝ 1/√spp, time ∝ spp).",
        runs.join(", ")
    )?;
    Ok(out)
}

/// `targets.csv` in one paragraph, for the README.
fn targets_summary(dir: &Path) -> Result<String> {
    let (csv, _, targets) = load_targets(dir)?;
    let mut out = csv.source();
    out.push('\n');
    for t in &targets {
        let speedup = t
            .path_tracer
            .map(|(p, _)| {
                format!(
                    "; path tracer {}, {:.0}× longer",
                    path_tracer_phrase(t.path_tracer),
                    p / t.median
                )
            })
            .unwrap_or_default();
        writeln!(
            out,
            "- {:.0} % in {} s: {:.2} % in {} s (`{}`){speedup}",
            t.target_error * 100.0,
            t.target_s,
            t.error * 100.0,
            secs3(t.median),
            t.flags,
        )?;
    }
    Ok(out)
}

/// `cornell_image.csv` as `(group, label, elements, steps, seconds, error)`.
type CornellRow = (String, String, String, String, f64, f64);

fn load_cornell_image(dir: &Path) -> Result<(Csv, Vec<CornellRow>)> {
    let csv = Csv::load(dir, "cornell_image")?;
    let mut rows = Vec::new();
    for r in csv.records() {
        rows.push((
            r.text("group")?.to_string(),
            r.text("label")?.to_string(),
            r.text("elements")?.to_string(),
            r.text("steps")?.to_string(),
            r.num("seconds")?,
            r.num("image_error")?,
        ));
    }
    Ok((csv, rows))
}

/// An error, radiosity's time to it and the path tracer's (extrapolated or not).
type TimesTo = (f64, Option<f64>, Option<(f64, bool)>);

/// Radiosity's (shooting, default mesh) and the path tracer's time to each error.
fn cornell_image_times(rows: &[CornellRow]) -> Vec<TimesTo> {
    let shooting: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.0 == "solver" && r.1 == "shooting")
        .map(|r| (r.4, r.5))
        .collect();
    let traced: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.0 == "pathtracer")
        .map(|r| (r.4, r.5))
        .collect();
    [0.05, 0.02, 0.015, 0.01]
        .into_iter()
        .map(|limit| {
            (
                limit,
                first_time_below(shooting.iter().copied(), limit),
                path_tracer_time(&traced, limit),
            )
        })
        .collect()
}

/// The end point of each run of `bench --only cornell-image` (a solver curve's last row, every
/// other row), as a Markdown table: the bench prints it, the docs quote it.
pub(super) fn cornell_end_points<N: std::fmt::Display + PartialEq>(
    rows: &[(String, String, N, N, f64, f64)],
) -> String {
    let mut out = String::from(
        "| Cornell box vs path-traced reference | elements | steps / spp | seconds | image error |\n|---|---:|---:|---:|---:|\n",
    );
    for (g, l, n, k, t, e) in rows {
        let last_of_run = g != "solver"
            || rows
                .iter()
                .rfind(|r| r.0 == "solver" && r.1 == *l)
                .is_some_and(|r| r.3 == *k);
        if last_of_run {
            out.push_str(&format!(
                "| {g}: {l} | {n} | {k} | {t:.2} | {:.2} % |\n",
                e * 100.0
            ));
        }
    }
    out
}

/// `cornell_image.csv`: each run's end point (the solver curves' last rows), then the
/// times to 5 %, 2 %, 1.5 % and 1 %, as `bench --only cornell-image` prints them.
fn cornell_image(dir: &Path) -> Result<String> {
    let (csv, rows) = load_cornell_image(dir)?;
    let mut out = csv.source();
    out.push('\n');
    out.push_str(&cornell_end_points(&rows));
    out.push('\n');
    for (limit, rad, pt) in cornell_image_times(&rows) {
        let pt = match pt {
            Some((t, false)) => format!("{t:.2} s"),
            Some((t, true)) => format!("{t:.0} s (extrapolated)"),
            None => "–".into(),
        };
        writeln!(
            out,
            "- time to {:.1} %: radiosity (shooting, default mesh) {}; path tracer {pt}",
            limit * 100.0,
            rad.map(|t| format!("{t:.2} s"))
                .unwrap_or("not reached".into()),
        )?;
    }
    Ok(out)
}

/// `cornell_image.csv` in a few lines, for the README: the default mesh's two passes and
/// the path tracer's times.
fn cornell_image_summary(dir: &Path) -> Result<String> {
    let (csv, rows) = load_cornell_image(dir)?;
    let mut out = csv.source();
    out.push('\n');
    let find = |group: &str, label: &str| rows.iter().find(|r| r.0 == group && r.1 == label);
    for (group, what) in [
        ("density", "vertex pass (interpolated)"),
        ("density, direct pass", "`--pass direct`"),
    ] {
        if let Some(r) = find(group, "budget 20000") {
            writeln!(
                out,
                "- default mesh ({} elements), {what}: {:.2} % in {:.1} s",
                thousands(r.2.parse().unwrap_or(0)),
                r.5 * 100.0,
                r.4
            )?;
        }
    }
    let times: Vec<String> = cornell_image_times(&rows)
        .into_iter()
        .map(|(limit, _, pt)| format!("{:.1} % in {}", limit * 100.0, path_tracer_phrase(pt)))
        .collect();
    writeln!(
        out,
        "- path tracer (256², one run per spp): {}",
        times.join(", ")
    )?;
    Ok(out)
}

/// `meshing.csv`: uniform, discontinuity and adaptive meshing, as `bench --only meshing`
/// prints it.
fn meshing(dir: &Path) -> Result<String> {
    let csv = Csv::load(dir, "meshing")?;
    let mut out = csv.source();
    out.push_str(
        "\n| meshing | setting | elements | s | error | s, direct pass | error, direct pass |\n",
    );
    out.push_str("|---|---|---:|---:|---:|---:|---:|\n");
    for r in csv.records() {
        writeln!(
            out,
            "| {} | {} | {} | {:.2} | {:.2} % | {:.2} | {:.2} % |",
            r.text("kind")?,
            r.text("setting")?,
            r.text("elements")?,
            r.num("seconds")?,
            100.0 * r.num("error")?,
            r.num("seconds_direct")?,
            100.0 * r.num("error_direct")?,
        )?;
    }
    Ok(out)
}

/// `hierarchical.csv`: hierarchical and wavelet radiosity against shooting on the Cornell
/// box; "(default)" marks the default link tolerance.
fn hierarchical(dir: &Path) -> Result<String> {
    let csv = Csv::load(dir, "hierarchical")?;
    let mut out = csv.source();
    out.push_str(
        "\n| solver | link tolerance | steps | solve s | error % | stored MB | peak MB |\n",
    );
    out.push_str("|---|---|---:|---:|---:|---:|---:|\n");
    for r in csv.records() {
        let tolerance = r.opt("link_tolerance")?;
        let default = if tolerance == Some(DEFAULT_LINK_TOLERANCE) {
            " (default)"
        } else {
            ""
        };
        writeln!(
            out,
            "| {}{default} | {} | {} | {:.2} | {:.2} | {} | {} |",
            r.text("solver")?,
            or_dash(tolerance.map(|_| r.text("link_tolerance").unwrap_or("").to_string())),
            thousands(r.num("steps")? as u64),
            r.num("solve_seconds")?,
            100.0 * r.num("image_error")?,
            r.text("stored_mb")?,
            r.text("peak_rss_mb")?,
        )?;
    }
    Ok(out)
}

/// `large.csv`: the gallery and the million-element Cornell box.
fn large(dir: &Path) -> Result<String> {
    let csv = Csv::load(dir, "large")?;
    let mut out = csv.source();
    out.push_str("\n| scene | solver | elements | steps | s to 1 % | s | residual | error % | stored MB | peak MB |\n");
    out.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in csv.records() {
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.1} | {:.1e} | {:.2} | {} | {} |",
            r.text("scene")?,
            r.text("solver")?,
            thousands(r.num("elements")? as u64),
            thousands(r.num("steps")? as u64),
            or_dash(r.opt("seconds_to_1pc")?.map(|t| format!("{t:.1}"))),
            r.num("seconds")?,
            r.num("residual")?,
            100.0 * r.num("image_error")?,
            r.text("stored_mb")?,
            r.text("peak_rss_mb")?,
        )?;
    }
    Ok(out)
}

/// A relative error in percent: two decimals below 10 %, one above.
fn percent(e: f64) -> String {
    let p = 100.0 * e;
    if p < 10.0 {
        format!("{p:.2} %")
    } else {
        format!("{p:.1} %")
    }
}

/// Seconds: two decimals below 1 s, one above.
fn secs2(t: f64) -> String {
    if t < 1.0 {
        format!("{t:.2}")
    } else {
        format!("{t:.1}")
    }
}

/// `specular.csv`: the hybrid against the path tracer on `cornell-specular` and
/// `cornell-glossy`.
fn specular(dir: &Path) -> Result<String> {
    let csv = Csv::load(dir, "specular")?;
    let mut out = csv.source();
    out.push_str("\n| method | setting | seconds | error | own error |\n");
    out.push_str("|---|---|---:|---:|---:|\n");
    for r in csv.records() {
        writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            r.text("method")?,
            r.text("setting")?,
            secs2(r.num("seconds")?),
            or_dash(r.opt("relative_rms")?.map(percent)),
            or_dash(r.opt("relative_rms_without_caustics")?.map(percent)),
        )?;
    }
    Ok(out)
}

/// `specular.csv` in a few lines, for the README: the hybrid's direct pass and the path
/// tracer's two longest runs.
fn specular_summary(dir: &Path) -> Result<String> {
    let csv = Csv::load(dir, "specular")?;
    let mut out = csv.source();
    out.push('\n');
    let mut traced = 0;
    for r in csv.records() {
        traced += usize::from(r.text("method")? == "path tracer");
    }
    let mut seen = 0;
    for r in csv.records() {
        let method = r.text("method")?;
        let traced_row = method == "path tracer";
        seen += usize::from(traced_row);
        let errors: Vec<String> = [
            ("from the full reference", r.opt("relative_rms")?),
            (
                "from the caustic-free path tracer",
                r.opt("relative_rms_without_caustics")?,
            ),
        ]
        .into_iter()
        .filter_map(|(what, e)| e.map(|e| format!("{} {what}", percent(e))))
        .collect();
        // The direct pass (the hybrid's best) and the path tracer's two longest runs.
        let wanted = method.ends_with("direct pass") || (traced_row && seen + 2 > traced);
        if wanted {
            writeln!(
                out,
                "- {method}, {}: {} in {} s",
                r.text("setting")?,
                errors.join(", "),
                secs2(r.num("seconds")?)
            )?;
        }
    }
    Ok(out)
}

/// `live_edits.csv`: material edits on a converged Cornell solve.
fn live_edits(dir: &Path) -> Result<String> {
    let csv = Csv::load(dir, "live_edits")?;
    let mut out = csv.source();
    out.push_str("\n| live edit (Cornell, default mesh) | edit's power / emitted | shots | seconds to 1 % of it |\n");
    out.push_str("|---|---:|---:|---:|\n");
    for r in csv.records() {
        writeln!(
            out,
            "| {} | {:.3} | {} | {:.3} |",
            r.text("edit")?,
            r.num("edit_power_fraction")?,
            r.text("shots")?,
            r.num("seconds")?,
        )?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_with_a_comma_and_space_stay_whole() {
        assert_eq!(
            split_fields("hybrid, vertex pass,16 spp, 18912 elements,4.705,0.38601,"),
            [
                "hybrid, vertex pass",
                "16 spp, 18912 elements",
                "4.705",
                "0.38601",
                ""
            ]
        );
    }

    #[test]
    fn a_csv_needs_its_provenance_and_whole_rows() {
        let ok = "# command: nusselt bench\n# date: 2026-12-01\na,b\n1,2\n";
        let csv = Csv::parse("x.csv", ok).expect("parses");
        assert_eq!(
            (csv.command.as_str(), csv.date.as_str()),
            ("nusselt bench", "2026-12-01")
        );
        assert_eq!(csv.rows, [["1", "2"]]);
        assert!(Csv::parse("x.csv", "a,b\n1,2\n").is_err());
        let short = Csv::parse("x.csv", "# command: c\n# date: d\na,b\n1\n");
        assert!(format!("{:#}", short.err().expect("fails")).contains("x.csv:4"));
    }

    #[test]
    fn regions_are_replaced_and_unknown_names_refused() {
        let doc = Path::new("d.md");
        let dir = Path::new("/nonexistent");
        let text = "a\n<!-- bench:table nothing -->\nold\n<!-- /bench:table -->\nb\n";
        let err = rewrite(text, doc, dir).expect_err("unknown name");
        assert!(err.to_string().contains("d.md:2"), "{err}");
        let (same, n) = rewrite("no regions\n", doc, dir).expect("no regions");
        assert_eq!((same.as_str(), n), ("no regions\n", 0));
    }

    #[test]
    fn number_formats() {
        assert_eq!(thousands(1014240), "1,014,240");
        assert_eq!(thousands(871), "871");
        assert_eq!(
            (secs3(0.12), secs3(1.297), secs3(11.535)),
            ("0.120".into(), "1.30".into(), "11.5".into())
        );
    }
}
