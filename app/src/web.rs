//! The browser entry point: the same studio on the `tagsmith_canvas` canvas of `app/index.html`.

use crate::studio::files::WebFiles;
use crate::studio::StudioApp;
use wasm_bindgen::JsCast;

pub fn start() {
    eframe::WebLogger::init(log::LevelFilter::Info).ok();
    // The detection worker (app/worker.js) runs this same module.
    if crate::studio::offload::web::in_worker() {
        crate::studio::offload::web::serve_in_worker();
        return;
    }
    wasm_bindgen_futures::spawn_local(async {
        if let Err(e) = load_assets().await {
            show_failure(&format!("The studio could not load its files: {e}"));
            return;
        }
        let canvas = web_sys::window()
            .and_then(|w| w.document())
            .and_then(|d| d.get_element_by_id("tagsmith_canvas"))
            .and_then(|e| e.dyn_into::<web_sys::HtmlCanvasElement>().ok())
            .expect("index.html has a <canvas id=\"tagsmith_canvas\">");
        let started = eframe::WebRunner::new()
            .start(
                canvas,
                eframe::WebOptions::default(),
                Box::new(|cc| {
                    use_the_label_font(&cc.egui_ctx);
                    let app = StudioApp::new(cc, Box::new(WebFiles::default()));
                    Ok(Box::new(FollowsAddress::new(app, &cc.egui_ctx)))
                }),
            )
            .await;
        if let Err(e) = started {
            log::error!("the studio could not start: {e:?}");
        }
    });
}

/// The browser build has no egui fonts of its own (`eframe`'s `default_fonts` is a desktop
/// feature): its text is drawn in the DejaVu Sans the core embeds for sheet labels, which covers
/// every symbol the studio writes (° × ≤ σ …).
fn use_the_label_font(ctx: &egui::Context) {
    let mut fonts = egui::FontDefinitions::empty();
    fonts.font_data.insert(
        "DejaVu Sans".into(),
        std::sync::Arc::new(egui::FontData::from_static(
            tagsmith::render::pdf::label_font(),
        )),
    );
    for family in [egui::FontFamily::Proportional, egui::FontFamily::Monospace] {
        fonts.families.insert(family, vec!["DejaVu Sans".into()]);
    }
    ctx.set_fonts(fonts);
}

/// The studio, following the page's address: `…/#detect=SAMPLE` opens the Detect panel on that
/// shipped sample, at start and whenever the address changes to it. A link that shows the
/// detector at work, and how scripts/web-detect.sh measures it in headless Chromium.
struct FollowsAddress {
    app: StudioApp,
    seen: String,
    _on_change: wasm_bindgen::closure::Closure<dyn FnMut()>,
}

impl FollowsAddress {
    fn new(mut app: StudioApp, ctx: &egui::Context) -> Self {
        let seen = address_hash();
        open_from_address(&mut app, &seen, ctx);
        let repaint = ctx.clone();
        // A new address draws a frame, which reads it.
        let on_change =
            wasm_bindgen::closure::Closure::<dyn FnMut()>::new(move || repaint.request_repaint());
        if let Some(window) = web_sys::window() {
            window.set_onhashchange(Some(on_change.as_ref().unchecked_ref()));
        }
        Self {
            app,
            seen,
            _on_change: on_change,
        }
    }
}

impl eframe::App for FollowsAddress {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let hash = address_hash();
        if hash != self.seen {
            open_from_address(&mut self.app, &hash, ui.ctx());
            self.seen = hash;
        }
        eframe::App::ui(&mut self.app, ui, frame);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        self.app.save(storage);
    }

    fn auto_save_interval(&self) -> std::time::Duration {
        self.app.auto_save_interval()
    }
}

fn address_hash() -> String {
    web_sys::window()
        .and_then(|w| w.location().hash().ok())
        .unwrap_or_default()
}

fn open_from_address(app: &mut StudioApp, hash: &str, ctx: &egui::Context) {
    if let Some(query) = hash.strip_prefix("#compare=") {
        if let Err(e) = compare_from_address(app, query, ctx) {
            // The words scripts/browser/compare.mjs waits for, as for a run that fails.
            log::error!("comparison stopped: {e}");
            app.studio.error(e);
        }
    }
    if let Some(sample) = hash.strip_prefix("#detect=") {
        // "#detect=NAME~2": the same sample again, as a new address.
        let sample = sample.split('~').next().unwrap_or_default();
        if !crate::studio::detect::open_sample(&mut app.studio, sample) {
            app.studio
                .error(format!("{sample}: no such sample (see assets/samples/)"));
        }
    }
}

/// `#compare=FAMILY,FAMILY[&scenes=N]`: the Compare panel runs the form's scenario for those
/// families (N scenes per swept value), in its worker; how scripts/web-compare.sh checks it.
fn compare_from_address(
    app: &mut StudioApp,
    query: &str,
    ctx: &egui::Context,
) -> Result<(), String> {
    let mut parts = query.split('&');
    let families: Vec<String> = (parts.next().unwrap_or_default().split(','))
        .filter(|f| !f.is_empty())
        .map(str::to_string)
        .collect();
    let studio = &mut app.studio;
    for part in parts {
        match part.split_once('=') {
            Some(("scenes", n)) => {
                studio.compare.scenario.scenes = n
                    .parse()
                    .map_err(|_| format!("#compare: scenes={n} is not a count"))?;
            }
            _ => return Err(format!("#compare: {part:?} is not scenes=N")),
        }
    }
    studio.compare.chosen = families;
    studio.panel = crate::studio::Panel::Compare;
    crate::studio::compare::run_chosen(studio, ctx)
}

/// Fetches the files the module does not embed ([`tagsmith::assets::all`]: the font, the
/// synthesis backgrounds, the samples, the detector's weights; `scripts/build-web.sh` copies
/// them to `assets/` beside the page) and hands them to the core. The page waits for them before the studio starts, the
/// worker before it serves; every request is sent at once, so they download side by side.
pub async fn load_assets() -> Result<(), String> {
    use wasm_bindgen_futures::JsFuture;
    let global = js_sys::global();
    let fetch: js_sys::Function = js_sys::Reflect::get(&global, &"fetch".into())
        .ok()
        .and_then(|f| f.dyn_into().ok())
        .ok_or("this browser has no fetch")?;
    let paths: Vec<&str> = tagsmith::assets::all().collect();
    let mut pending = Vec::new();
    for path in &paths {
        let url = format!("./assets/{path}");
        let promise = fetch
            .call1(&global, &url.as_str().into())
            .map_err(|e| format!("{url}: {e:?}"))?;
        pending.push((url, js_sys::Promise::from(promise)));
    }
    let mut files = Vec::new();
    for (path, (url, promise)) in paths.iter().zip(pending) {
        let response: web_sys::Response = JsFuture::from(promise)
            .await
            .and_then(|r| r.dyn_into())
            .map_err(|e| format!("{url}: {e:?}"))?;
        if !response.ok() {
            return Err(format!("{url}: HTTP {}", response.status()));
        }
        let buffer = JsFuture::from(
            response
                .array_buffer()
                .map_err(|e| format!("{url}: {e:?}"))?,
        )
        .await
        .map_err(|e| format!("{url}: {e:?}"))?;
        files.push((path.to_string(), js_sys::Uint8Array::new(&buffer).to_vec()));
    }
    tagsmith::assets::provide(files).map_err(|e| e.to_string())
}

/// Says on the page why the studio could not start (no canvas to draw it on yet).
fn show_failure(message: &str) {
    log::error!("{message}");
    if let Some(body) = web_sys::window()
        .and_then(|w| w.document())
        .and_then(|d| d.body())
    {
        body.set_inner_html("");
        let _ = body.append_with_str_1(message);
    }
}
