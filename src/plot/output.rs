//! Fonts and file handling: the embedded font, atomic PNG and SVG files.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::ffi::OsString;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use super::*;

/// Registers the embedded DejaVu Sans fonts under [`FONT`] exactly once.
pub(super) fn ensure_fonts() -> Result<(), String> {
    static FONTS: OnceLock<Result<(), String>> = OnceLock::new();
    FONTS
        .get_or_init(|| {
            register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
                .map_err(|_| "cannot load embedded DejaVu Sans font".to_string())?;
            register_font(FONT, FontStyle::Bold, dejavu::sans::bold())
                .map_err(|_| "cannot load embedded DejaVu Sans Bold font".to_string())?;
            Ok(())
        })
        .clone()
}

/// A figure that can be rendered on any plotters backend.
pub(super) trait Figure {
    /// Figure size in pixels.
    fn size(&self) -> (u32, u32);
    /// Draws the figure on a white root area.
    fn render<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>;
}

/// `path` with `suffix` appended to its final component.
pub(super) fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut s: OsString = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// Converts any displayable backend error into a message.
pub(super) fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

pub(super) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> PlotError + '_ {
    move |source| PlotError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Removes a leftover temporary file or directory of an earlier crashed run.
pub(super) fn remove_stale(tmp: &Path) {
    if let Ok(meta) = fs::symlink_metadata(tmp) {
        let _ = if meta.is_dir() {
            fs::remove_dir_all(tmp)
        } else {
            fs::remove_file(tmp)
        };
    }
}

pub(super) fn save_figure<F: Figure + Sync>(
    fig: &F,
    stem: &Path,
) -> Result<Vec<PathBuf>, PlotError> {
    if stem.file_name().is_none() {
        return Err(PlotError::InvalidInput(format!(
            "output stem {} has no file name",
            stem.display()
        )));
    }
    ensure_fonts().map_err(|message| PlotError::Backend {
        path: stem.to_path_buf(),
        message,
    })?;
    if let Some(parent) = stem.parent() {
        if !parent.as_os_str().is_empty() {
            fs::create_dir_all(parent).map_err(io_err(parent))?;
        }
    }
    let png = with_suffix(stem, ".png");
    let svg = with_suffix(stem, ".svg");
    // The two renderings share nothing but the figure: side by side they halve the time
    // of the slowest figure, which is what a report waits for.
    let (drawn_png, drawn_svg) = rayon::join(|| write_png(fig, &png), || write_svg(fig, &svg));
    drawn_png?;
    drawn_svg?;
    Ok(vec![png, svg])
}

/// Renders the PNG atomically.
///
/// The bitmap encoder picks the image format from the file extension, so
/// the image is drawn to `<stem>.png.tmp/<name>.png` (a temporary directory
/// next to the target) and then renamed to `<stem>.png`.
pub(super) fn write_png<F: Figure>(fig: &F, target: &Path) -> Result<(), PlotError> {
    let tmp_dir = with_suffix(target, ".tmp");
    remove_stale(&tmp_dir);
    fs::create_dir(&tmp_dir).map_err(io_err(&tmp_dir))?;
    let name = target.file_name().unwrap_or_else(|| "figure.png".as_ref());
    let tmp_file = tmp_dir.join(name);
    // The backend is dropped inside `draw`, before the clean-up.
    let result = draw(fig, BitMapBackend::new(&tmp_file, fig.size()), target)
        .and_then(|_| fs::rename(&tmp_file, target).map_err(io_err(target)));
    let _ = fs::remove_dir_all(&tmp_dir);
    result
}

/// Draws `fig` on a white background with `backend`; errors name `target`.
pub(super) fn draw<F: Figure, DB: DrawingBackend>(
    fig: &F,
    backend: DB,
    target: &Path,
) -> Result<(), PlotError> {
    let root = backend.into_drawing_area();
    root.fill(&WHITE)
        .map_err(err)
        .and_then(|_| fig.render(&root))
        .and_then(|_| root.present().map_err(err))
        .map_err(|message| PlotError::Backend {
            path: target.to_path_buf(),
            message,
        })
}

/// Renders the SVG atomically via `<stem>.svg.tmp`.
pub(super) fn write_svg<F: Figure>(fig: &F, target: &Path) -> Result<(), PlotError> {
    let tmp = with_suffix(target, ".tmp");
    remove_stale(&tmp);
    let result = draw(fig, SVGBackend::new(&tmp, fig.size()), target)
        .and_then(|_| fs::rename(&tmp, target).map_err(io_err(target)));
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}
