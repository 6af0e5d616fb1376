//! The display of `cdlab sweep`: one implementation of [`crate::campaign::Watch`]; its
//! bars here, its messages in `cli/campaign_messages.rs`.

use std::io::IsTerminal;
use std::sync::OnceLock;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use crate::campaign::{Event, Point, Watch};

use super::run::{Display, Progress};

/// The campaign's display: on a terminal, a bar of finished tests and one line per running
/// test; in a log, each test's start and end, and a line per running test every
/// `log_every` seconds.
pub struct CampaignDisplay {
    pub(super) multi: Option<MultiProgress>,
    /// The bar of finished tests, set once the campaign knows its length.
    pub overall: OnceLock<ProgressBar>,
    log_every: f64,
}

impl CampaignDisplay {
    /// The display of a campaign whose tests log a line every `log_every` seconds.
    pub fn new(log_every: f64) -> Self {
        let multi = std::io::stderr().is_terminal().then(MultiProgress::new);
        CampaignDisplay {
            multi,
            overall: OnceLock::new(),
            log_every,
        }
    }

    /// Prints a line above the bars, or on stderr.
    pub(super) fn say(&self, line: &str) {
        match &self.multi {
            Some(m) => {
                let _ = m.println(line);
            }
            None => note!("{line}"),
        }
    }
}

/// One running test's line in the campaign's display, removed when the test is done.
struct TestLine<'a> {
    display: Display,
    multi: Option<&'a MultiProgress>,
    bar: Option<ProgressBar>,
}

impl crate::run::Progress for TestLine<'_> {
    fn event(&mut self, event: &crate::run::Event<'_>) {
        self.display.event(event);
    }
}

impl Drop for TestLine<'_> {
    fn drop(&mut self) {
        if let (Some(m), Some(b)) = (self.multi, &self.bar) {
            m.remove(b);
        }
    }
}

impl Watch for CampaignDisplay {
    fn event(&self, event: &Event<'_>) {
        // The messages are in cli/campaign_messages.rs.
        self.show(event);
    }

    fn test(&self, point: &Point) -> Box<dyn crate::run::Progress + '_> {
        let label = point
            .dir
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into());
        let bar = self.multi.as_ref().map(|m| {
            let b = m.add(ProgressBar::new(1000));
            b.set_style(
                ProgressStyle::with_template("  {prefix:<22} {bar:20} {msg}").expect("valid template"),
            );
            b.set_prefix(label.clone());
            b
        });
        let display = Progress::Campaign {
            label,
            bar: bar.clone(),
            every_s: self.log_every,
        }
        .display();
        Box::new(TestLine {
            display,
            multi: self.multi.as_ref(),
            bar,
        })
    }
}
