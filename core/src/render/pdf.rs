//! Multi-page vector PDF from sheet pages: each page's SVG goes through svg2pdf as a form XObject
//! scaled to the page's exact size in points.

use super::scene::RenderError;
use super::sheet::Sheet;
use pdf_writer::{Content, Finish, Name, Pdf, Rect, Ref};
use std::collections::HashMap;
use std::sync::{Arc, OnceLock};
use svg2pdf::usvg;

/// The label font (DejaVu Sans), the same on every machine so that every machine produces the
/// same PDF: the browser studio draws its text with it too, so the page loads one font rather
/// than this and egui's own.
pub fn label_font() -> &'static [u8] {
    crate::assets::file(crate::assets::LABEL_FONT)
}

pub const PT_PER_MM: f64 = 72.0 / 25.4;

fn svg_options() -> &'static usvg::Options<'static> {
    static OPTIONS: OnceLock<usvg::Options<'static>> = OnceLock::new();
    OPTIONS.get_or_init(|| {
        let mut db = usvg::fontdb::Database::new();
        db.load_font_data(label_font().to_vec());
        usvg::Options {
            fontdb: Arc::new(db),
            font_family: "DejaVu Sans".into(),
            ..usvg::Options::default()
        }
    })
}

/// Parses an SVG produced by this crate (with the embedded font available for its text).
pub fn parse_svg(svg: &str) -> Result<usvg::Tree, RenderError> {
    usvg::Tree::from_str(svg, svg_options()).map_err(|e| match e {
        // usvg reads at most a million elements (its guard against hostile files): a page of many
        // markers at the family limits can pass it. That is a request too large to print on one
        // page, not a failure to encode.
        usvg::Error::ElementsLimitReached
        | usvg::Error::ParsingFailed(usvg::roxmltree::Error::NodesLimitReached) => {
            RenderError::Layout(
                "the page would draw more than 1 000 000 shapes; print fewer markers per page \
                 (--ids, a larger --size-mm) or a family with simpler patterns"
                    .into(),
            )
        }
        e => RenderError::Encode(format!("SVG: {e}")),
    })
}

pub fn sheet_pdf(sheet: &Sheet) -> Result<Vec<u8>, RenderError> {
    let mut alloc = Ref::new(1);
    let catalog = alloc.bump();
    let tree_ref = alloc.bump();
    let (w_pt, h_pt) = (
        (sheet.page.width_mm * PT_PER_MM) as f32,
        (sheet.page.height_mm * PT_PER_MM) as f32,
    );
    let mut pdf = Pdf::new();
    let mut page_refs = Vec::with_capacity(sheet.pages.len());
    let mut chunks = Vec::with_capacity(sheet.pages.len());
    for svg in &sheet.pages {
        let tree = parse_svg(svg)?;
        let (chunk, svg_ref) = svg2pdf::to_chunk(&tree, svg2pdf::ConversionOptions::default())
            .map_err(|e| RenderError::Encode(format!("PDF: {e}")))?;
        let mut map = HashMap::new();
        let chunk = chunk.renumber(|old| *map.entry(old).or_insert_with(|| alloc.bump()));
        let svg_ref = map[&svg_ref];
        let (page_ref, content_ref) = (alloc.bump(), alloc.bump());
        let name = Name(b"S1");
        let mut page = pdf.page(page_ref);
        page.media_box(Rect::new(0.0, 0.0, w_pt, h_pt));
        page.parent(tree_ref);
        page.contents(content_ref);
        page.resources().x_objects().pair(name, svg_ref);
        page.finish();
        let mut content = Content::new();
        // svg2pdf's XObject spans one unit square; stretch it over the page.
        content
            .transform([w_pt, 0.0, 0.0, h_pt, 0.0, 0.0])
            .x_object(name);
        pdf.stream(content_ref, &content.finish());
        page_refs.push(page_ref);
        chunks.push(chunk);
    }
    pdf.catalog(catalog).pages(tree_ref);
    pdf.pages(tree_ref)
        .kids(page_refs.iter().copied())
        .count(page_refs.len() as i32);
    for chunk in &chunks {
        pdf.extend(chunk);
    }
    Ok(pdf.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_page_past_the_svg_element_limit_is_a_layout_error() {
        let shapes = "<rect width=\"1\" height=\"1\"/>".repeat(1_000_100);
        let svg = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"10\" height=\"10\">{shapes}</svg>"
        );
        let err = parse_svg(&svg).unwrap_err();
        assert!(matches!(err, RenderError::Layout(_)), "{err}");
        assert!(err.to_string().contains("fewer markers"), "{err}");
    }
}
