//! The page and its assets, built from `web/` by `npm run build` (esbuild bundles the page's
//! code with three.js into one file) and committed under `web/dist/`, embedded here: building
//! raisov needs neither npm nor a network. three.js is MIT-licensed; its licence is served
//! beside the bundle as `/THREE-LICENSE.txt`.

/// `index.html`.
pub const INDEX_HTML: &[u8] = include_bytes!("../web/dist/index.html");
/// The bundled page code (three.js included).
pub const APP_JS: &[u8] = include_bytes!("../web/dist/app.js");
/// three.js's licence.
pub const THREE_LICENSE: &[u8] = include_bytes!("../web/dist/THREE-LICENSE.txt");

/// The asset at `path` and its content type.
pub fn get(path: &str) -> Option<(&'static [u8], &'static str)> {
    Some(match path {
        "/" | "/index.html" => (INDEX_HTML, "text/html; charset=utf-8"),
        "/app.js" => (APP_JS, "text/javascript; charset=utf-8"),
        "/THREE-LICENSE.txt" => (THREE_LICENSE, "text/plain; charset=utf-8"),
        _ => return None,
    })
}
