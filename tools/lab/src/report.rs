//! The HTML reports of runs and experiments: one generator for `demo`, `sim`, `v2t-sim-ecu` and
//! every `experiment`.
//!
//! A report is one self-contained file: inline SVG, inline CSS and a little inline script, nothing
//! fetched from the network. It reads the same printed to PDF (the details open, the slider hidden,
//! the moments that matter drawn as fixed footprints). Every page states where its figures come
//! from ([`Page::provenance`]).
//!
//! - [`run`]: one run — the map, the routes and driven paths, footprints at the key moments and a
//!   time slider that moves them, speed, acceleration and predicted PET over time, the regulator's
//!   status and the gate's state, the zone-occupancy timeline, the realism, links to the run's
//!   files.
//! - [`experiment`]: an experiment or campaign — the per-VUT table, every run's PET as a strip per
//!   case, the steering error against τ, the methods side by side, and each case's runs.

use std::fmt::Write as _;

pub mod experiment;
pub mod plot;
pub mod run;

/// Text for HTML (element content and attribute values): the project's one escape.
pub use v2t_model::text::xml_escape as esc;

/// An HTML page of the report.
#[derive(Debug, Clone, Default)]
pub struct Page {
    /// Title.
    pub title: String,
    /// Where the figures come from: the world (simulated proving ground, SUMO), the VUT models,
    /// the data and the seeds. Shown under the title.
    pub provenance: Vec<String>,
    /// The body, built from [`run::section`], [`experiment`] parts and [`table`].
    pub body: String,
}

impl Page {
    /// A page with `title`.
    pub fn new(title: &str) -> Self {
        Self { title: title.to_owned(), ..Self::default() }
    }

    /// The whole HTML document.
    pub fn html(&self) -> String {
        let mut h = String::with_capacity(self.body.len() + 8192);
        let _ = write!(
            h,
            "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><meta name=\"viewport\" content=\"width=device-width\">\
             <meta name=\"generator\" content=\"Video2Track {}\"><title>{}</title><style>{CSS}{}</style></head><body>\
             <header><h1>{}</h1>",
            env!("CARGO_PKG_VERSION"),
            esc(&self.title),
            plot::CSS,
            esc(&self.title)
        );
        if !self.provenance.is_empty() {
            h.push_str("<ul class=\"provenance\">");
            for p in &self.provenance {
                let _ = write!(h, "<li>{}</li>", esc(p));
            }
            h.push_str("</ul>");
        }
        h.push_str("</header><main>");
        h.push_str(&self.body);
        let _ = writeln!(h, "</main><script>{SCRIPT}</script></body></html>");
        h
    }
}

/// A table: header cells (none: no header row) and rows of cells (HTML already escaped by the
/// caller: use [`esc`]).
pub fn table(class: &str, header: &[&str], rows: &[Vec<String>]) -> String {
    let mut h = format!("<table class=\"{class}\">");
    if !header.is_empty() {
        h.push_str("<thead><tr>");
        for c in header {
            let _ = write!(h, "<th>{c}</th>");
        }
        h.push_str("</tr></thead>");
    }
    h.push_str("<tbody>");
    for r in rows {
        h.push_str("<tr>");
        for c in r {
            let _ = write!(h, "<td>{c}</td>");
        }
        h.push_str("</tr>");
    }
    h.push_str("</tbody></table>");
    h
}

/// A number with `decimals`, or `–`.
pub fn num(v: Option<f64>, decimals: usize) -> String {
    v.filter(|x| x.is_finite()).map_or_else(|| "–".to_owned(), |x| format!("{x:.decimals$}"))
}

/// A fraction as a percentage with one decimal, or `–`.
pub fn pct(v: Option<f64>) -> String {
    v.filter(|x| x.is_finite()).map_or_else(|| "–".to_owned(), |x| format!("{:.1} %", 100.0 * x))
}

const CSS: &str = "\
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;max-width:1180px;margin:1.5em auto;padding:0 1em;color:#1d1d1f;font-size:14px}\
h1{font-size:1.6em;margin:.2em 0}h2{font-size:1.3em;margin-top:1.6em;border-bottom:1px solid #ddd}h3{font-size:1.05em}\
.provenance{color:#555;font-size:.92em;padding-left:1.2em}\
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #d0d0d0;padding:3px 7px;text-align:right;vertical-align:top}\
th{background:#f2f2f4}td:first-child,th:first-child{text-align:left}.facts td{text-align:left}.facts td:first-child{color:#555;white-space:nowrap}\
.warn{color:#b00020}.ok{color:#0a7a3e}.muted{color:#777}\
.grid2{display:flex;flex-wrap:wrap;gap:10px;align-items:flex-start}.col{display:flex;flex-direction:column;gap:10px}\
figure{margin:0}.scroll{overflow-x:auto;max-width:100%}svg{flex:none}.mapfig{max-width:580px}figcaption{font-size:.85em}.run{margin-bottom:2em}\
svg{background:#fff;border:1px solid #e2e2e2}\
.controls{display:flex;align-items:center;gap:8px;flex-wrap:wrap;margin:.4em 0}.controls input[type=range]{width:420px}\
.controls button{font-size:12px;padding:2px 6px}.readout{font-family:ui-monospace,monospace;font-size:12px}\
.links a{margin-right:1em}details{margin:.3em 0}summary{cursor:pointer}\
.map .route{fill:none;stroke:#9a9a9a;vector-effect:non-scaling-stroke;stroke-width:1;stroke-dasharray:4 3}\
.map .driven{fill:none;vector-effect:non-scaling-stroke;stroke-width:2}\
.map .zone{fill:none;stroke:#d00;stroke-opacity:.28;stroke-linecap:butt}\
.map .ghost{fill:none;vector-effect:non-scaling-stroke;stroke-width:1.2;stroke-dasharray:3 2}\
.map .fp{stroke:#111;vector-effect:non-scaling-stroke;stroke-width:1}\
@media print{body{max-width:none;margin:0}.controls{display:none}.run{break-inside:avoid-page}h2{break-after:avoid}\
details>summary{list-style:none}svg{break-inside:avoid}}";

/// The page's script: the time sliders of the runs, the cursors of their plots, opening every
/// `<details>` before printing, and what a test reads back (`data-errors`, `data-ready-ms`).
const SCRIPT: &str = r#"
(function(){
var root=document.documentElement;var errors=[];
function fail(m){errors.push(String(m));root.setAttribute('data-errors',errors.join(' | '));}
window.addEventListener('error',function(e){fail(e.message||e);});
function fmt(v,d){return (v===null||v===undefined||!isFinite(v))?'–':v.toFixed(d);}
function setup(run){
  var el=run.querySelector('script.rundata');if(!el){return;}
  var d=JSON.parse(el.textContent);var n=d.t.length;if(n===0){return;}
  var slider=run.querySelector('input.slider');var out=run.querySelector('.readout');
  var fps=run.querySelectorAll('g.fp');var plots=run.querySelectorAll('svg[data-x0]');
  function show(k){
    k=Math.max(0,Math.min(n-1,k|0));var t=d.t[k];var parts=['t = '+fmt(t,2)+' s'];
    for(var i=0;i<d.agents.length;i++){var a=d.agents[i];var g=fps[i];
      if(g){g.setAttribute('transform','translate('+a.x[k]+' '+a.y[k]+') rotate('+(a.h[k]*180/Math.PI)+')');}
      parts.push(a.id+' '+fmt(a.v[k],1)+' m/s');}
    if(d.pet&&d.pet[k]!==null){parts.push('predicted PET '+fmt(d.pet[k],2)+' s');}
    for(var j=0;j<plots.length;j++){var p=plots[j];var x0=+p.dataset.x0,x1=+p.dataset.x1,a0=+p.dataset.px0,a1=+p.dataset.px1;
      var c=p.querySelector('.cursor');if(c&&x1>x0){var px=a0+(Math.max(x0,Math.min(x1,t))-x0)/(x1-x0)*(a1-a0);c.setAttribute('x1',px);c.setAttribute('x2',px);}}
    if(out){out.textContent=parts.join('   ');}
    if(slider&&(+slider.value)!==k){slider.value=k;}
  }
  function nearest(t){var best=0;for(var k=0;k<n;k++){if(Math.abs(d.t[k]-t)<Math.abs(d.t[best]-t)){best=k;}}return best;}
  if(slider){slider.addEventListener('input',function(){show(+slider.value);});}
  var buttons=run.querySelectorAll('button[data-t]');
  for(var b=0;b<buttons.length;b++){(function(btn){btn.addEventListener('click',function(){show(nearest(+btn.dataset.t));});})(buttons[b]);}
  show(d.start===undefined?0:nearest(d.start));
}
try{var runs=document.querySelectorAll('section.run');for(var r=0;r<runs.length;r++){setup(runs[r]);}}catch(e){fail(e.message||e);}
window.addEventListener('beforeprint',function(){var ds=document.querySelectorAll('details');for(var i=0;i<ds.length;i++){ds[i].open=true;}});
root.setAttribute('data-ready-ms',String(Math.round(performance.now())));
})();
"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_for_content_and_attributes() {
        assert_eq!(esc("<a href=\"x\">'&'</a>"), "&lt;a href=&quot;x&quot;&gt;&#39;&amp;&#39;&lt;/a&gt;");
    }

    #[test]
    fn a_page_fetches_nothing_and_states_its_provenance() {
        let mut p = Page::new("A <test>");
        p.provenance.push("simulated proving ground".into());
        p.body = table("t", &["a"], &[vec!["1".into()]]);
        let html = p.html();
        assert!(html.contains("<title>A &lt;test&gt;</title>") && html.contains("<li>simulated proving ground</li>"));
        for fetch in ["http://", "https://", "src=", "@import", "url("] {
            assert!(!html.contains(fetch), "`{fetch}` in a self-contained page");
        }
    }
}
