/* sins report: interactive SVG plots, linked zoom and sortable tables, with no dependency.
 * Reads the JSON of the page's element id="sins-data" (a script of type application/json): {plots: [...]}.
 * A plot: {id, kind: "line"|"plan"|"box", title, xlabel, ylabel, group, logy, x0,
 *          series: [{name, x, y, lo, hi, style: "line"|"points"|"band"|"marker", dash, color}],
 *          spans: [[x_a, x_b], ...] (shaded time intervals), spanlabel,
 *          boxes: [{name, p5, p25, p50, p75, p95, min, max}] (kind "box")}.
 * Drag on a plot to zoom (x for time plots, a rectangle for the plan view), double-click to reset;
 * time plots of one group share their x-range.  window.sinsPlots exposes the state for tests.
 */
(function () {
  "use strict";
  var NS = "http://www.w3.org/2000/svg";
  var COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
                "#bcbd22", "#7f7f7f"];
  var DASHES = ["", "6 3", "2 2", "8 3 2 3"];
  var W = 860, H = 280, M = {l: 78, r: 14, t: 10, b: 40};
  var plots = {}, groups = {};

  function el(name, attrs, parent) {
    var e = document.createElementNS(NS, name);
    for (var k in attrs) { if (attrs[k] !== null && attrs[k] !== undefined) e.setAttribute(k, attrs[k]); }
    if (parent) parent.appendChild(e);
    return e;
  }
  function fmt(v) {
    if (v === 0) return "0";
    var a = Math.abs(v);
    if (a >= 1e5 || a < 1e-3) return v.toExponential(2).replace("e+", "e");
    return String(Number(v.toPrecision(6)));
  }
  function niceTicks(a, b, n) {
    if (!(b > a)) { b = a + 1; }
    var step = Math.pow(10, Math.floor(Math.log10((b - a) / n)));
    var err = (b - a) / n / step;
    if (err >= 7.5) step *= 10; else if (err >= 3.5) step *= 5; else if (err >= 1.5) step *= 2;
    var out = [];
    for (var v = Math.ceil(a / step) * step; v <= b + step * 1e-9; v += step) out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    return out;
  }
  /* Ticks of a log axis spanning log10 values [a, b]: [position (log10 of the value), label].  Exact decades
   * ("1e-2") when two fit; else 1, 2, 5 (then every digit) times the decades, labelled with their values
   * ("0.03"); else (less than a factor 1.25) evenly spaced values.  Never a fractional exponent. */
  function logTicks(a, b) {
    var out = [], e, i;
    for (e = Math.floor(a); e <= Math.ceil(b); e++) if (e >= a - 1e-9 && e <= b + 1e-9) out.push([e, "1e" + e]);
    if (out.length >= 2) return out;
    var sets = [[1, 2, 5], [1, 2, 3, 4, 5, 6, 7, 8, 9]];
    for (i = 0; i < sets.length; i++) {
      out = [];
      for (e = Math.floor(a); e <= Math.ceil(b); e++) {
        sets[i].forEach(function (m) {
          var pos = e + Math.log10(m);
          if (pos >= a - 1e-9 && pos <= b + 1e-9) out.push([pos, fmt(Number((m * Math.pow(10, e)).toPrecision(12)))]);
        });
      }
      if (out.length >= 2) return out;
    }
    return niceTicks(Math.pow(10, a), Math.pow(10, b), 4).filter(function (v) { return v > 0; })
      .map(function (v) { return [Math.log10(v), fmt(v)]; });
  }
  function range(vals, lo, hi) {
    for (var i = 0; i < vals.length; i++) {
      var v = vals[i];
      if (v === null || !isFinite(v)) continue;
      if (v < lo) lo = v;
      if (v > hi) hi = v;
    }
    return [lo, hi];
  }
  function pad(r, f) {
    if (!(r[1] > r[0])) { var c = isFinite(r[0]) ? r[0] : 0, d = Math.abs(c) * 0.1 || 1; return [c - d, c + d]; }
    var p = (r[1] - r[0]) * f;
    return [r[0] - p, r[1] + p];
  }

  function ytransform(p, v) {
    if (!p.logy) return v;
    return (v === null || !(v > 0)) ? null : Math.log10(v);
  }

  /* The y-range of the data inside the x-range [a, b] (time plots) or of everything (plan). */
  function yrangeOf(p, a, b) {
    var lo = Infinity, hi = -Infinity;
    p.series.forEach(function (s) {
      if (s.hidden) return;
      var ys = s.style === "sigma" ? [s.s, s.s.map(function (v) { return v === null ? null : -v; })] : [s.y, s.lo, s.hi];
      for (var j = 0; j < 3; j++) {
        var arr = ys[j];
        if (!arr) continue;
        for (var i = 0; i < s.x.length; i++) {
          var x = s.x[i];
          if (p.kind !== "plan" && (x < a || x > b)) continue;
          var v = ytransform(p, arr[i]);
          if (v === null || !isFinite(v)) continue;
          if (v < lo) lo = v;
          if (v > hi) hi = v;
        }
      }
    });
    var fx = fullX(p), whole = a <= fx[0] + 1e-9 * (fx[1] - fx[0]) && b >= fx[1] - 1e-9 * (fx[1] - fx[0]);
    if (whole && p.robust && p.robust.length === 2) {   // the writer's robust y-range (start-up transient), unzoomed
      lo = Math.max(lo, p.robust[0]);
      hi = Math.min(hi, p.robust[1]);
    }
    if (lo === Infinity) return [0, 1];
    return pad([lo, hi], 0.05);
  }

  function fullX(p) {
    var r = [Infinity, -Infinity];
    p.series.forEach(function (s) { r = range(s.x, r[0], r[1]); });
    (p.spans || []).forEach(function (sp) { r = range(sp, r[0], r[1]); });
    if (r[0] === Infinity) return [0, 1];
    return p.kind === "plan" ? pad(r, 0.04) : (r[1] > r[0] ? r : pad(r, 0.05));
  }

  function pathOf(xs, ys, sx, sy, p) {
    var d = [], pen = false;
    for (var i = 0; i < xs.length; i++) {
      var y = ytransform(p, ys[i]);
      if (y === null || xs[i] === null || !isFinite(y)) { pen = false; continue; }
      d.push((pen ? "L" : "M") + sx(xs[i]).toFixed(1) + " " + sy(y).toFixed(1));
      pen = true;
    }
    return d.join("");
  }
  function bandOf(xs, lo, hi, sx, sy, p) {
    var parts = [], cur = [];
    function flush() {
      if (cur.length > 1) {
        var d = "M" + cur.map(function (i) { return sx(xs[i]).toFixed(1) + " " + sy(ytransform(p, hi[i])).toFixed(1); }).join("L");
        d += "L" + cur.slice().reverse().map(function (i) { return sx(xs[i]).toFixed(1) + " " + sy(ytransform(p, lo[i])).toFixed(1); }).join("L") + "Z";
        parts.push(d);
      }
      cur = [];
    }
    for (var i = 0; i < xs.length; i++) {
      if (lo[i] === null || hi[i] === null || ytransform(p, lo[i]) === null || ytransform(p, hi[i]) === null) flush();
      else cur.push(i);
    }
    flush();
    return parts.join("");
  }

  function draw(p) {
    var svg = p.svg;
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    var w = p.width, h = p.height;
    var xr = p.xr, yr = p.yr;
    if (p.kind === "plan") {          // equal scale in east and north
      var pw = w - M.l - M.r, ph = h - M.t - M.b;
      var ux = (xr[1] - xr[0]) / pw, uy = (yr[1] - yr[0]) / ph, u = Math.max(ux, uy);
      var cx = (xr[0] + xr[1]) / 2, cy = (yr[0] + yr[1]) / 2;
      xr = [cx - u * pw / 2, cx + u * pw / 2];
      yr = [cy - u * ph / 2, cy + u * ph / 2];
    }
    p.view = {x: xr, y: yr};
    svg.setAttribute("data-xmin", xr[0]);
    svg.setAttribute("data-xmax", xr[1]);
    var sx = function (x) { return M.l + (x - xr[0]) / (xr[1] - xr[0]) * (w - M.l - M.r); };
    var sy = function (y) { return h - M.b - (y - yr[0]) / (yr[1] - yr[0]) * (h - M.t - M.b); };
    p.sx = sx; p.sy = sy;
    el("rect", {x: M.l, y: M.t, width: w - M.l - M.r, height: h - M.t - M.b, fill: "#fff", stroke: "#999",
                "class": "frame"}, svg);
    var clipId = "clip-" + p.id;
    var defs = el("defs", {}, svg);
    var cp = el("clipPath", {id: clipId}, defs);
    el("rect", {x: M.l, y: M.t, width: w - M.l - M.r, height: h - M.t - M.b}, cp);
    var axes = el("g", {"class": "axes", "font-size": "11", fill: "#333"}, svg);
    niceTicks(xr[0], xr[1], 8).forEach(function (v) {
      var X = sx(v);
      el("line", {x1: X, x2: X, y1: M.t, y2: h - M.b, stroke: "#eee"}, axes);
      var t = el("text", {x: X, y: h - M.b + 14, "text-anchor": "middle"}, axes);
      t.textContent = fmt(v);
    });
    (p.logy ? logTicks(yr[0], yr[1]) : niceTicks(yr[0], yr[1], 5).map(function (v) { return [v, fmt(v)]; }))
      .forEach(function (tick) {
        var Y = sy(tick[0]);
        el("line", {x1: M.l, x2: w - M.r, y1: Y, y2: Y, stroke: "#eee"}, axes);
        var t = el("text", {x: M.l - 4, y: Y + 4, "text-anchor": "end"}, axes);
        t.textContent = tick[1];
      });
    var xl = el("text", {x: (M.l + w - M.r) / 2, y: h - 6, "text-anchor": "middle"}, axes);
    xl.textContent = p.xlabel || "";
    var yl = el("text", {x: 14, y: (M.t + h - M.b) / 2, "text-anchor": "middle",
                         transform: "rotate(-90 14 " + ((M.t + h - M.b) / 2) + ")"}, axes);
    yl.textContent = p.ylabel || "";
    var data = el("g", {"clip-path": "url(#" + clipId + ")", "class": "data"}, svg);
    (p.spans || []).forEach(function (sp) {
      var a = sx(sp[0]), b = sx(sp[1]);
      el("rect", {x: Math.min(a, b), y: M.t, width: Math.max(1, Math.abs(b - a)), height: h - M.t - M.b,
                  fill: "#f5d0a9", opacity: 0.5, "class": "span"}, data);
    });
    p.series.forEach(function (s) {
      if (s.hidden) return;
      var c = s.color;
      if (s.style === "sigma") {          // +-k sigma bands around zero, one per multiplier
        (s.mult || [1]).forEach(function (m, j) {
          var lo = s.s.map(function (v) { return v === null ? null : -m * v; });
          var hi = s.s.map(function (v) { return v === null ? null : m * v; });
          el("path", {d: bandOf(s.x, lo, hi, sx, sy, p), fill: c, "fill-opacity": (s.opacity || [0.15])[j],
                      stroke: "none", "class": "band"}, data);
        });
      } else if (s.style === "band") {
        el("path", {d: bandOf(s.x, s.lo, s.hi, sx, sy, p), fill: c, "fill-opacity": s.opacity || 0.15,
                    stroke: "none", "class": "band"}, data);
      } else if (s.style === "points" || s.style === "marker") {
        var g = el("g", {"class": "points", fill: c}, data);
        var r = s.style === "marker" ? 5 : 2;
        for (var i = 0; i < s.x.length; i++) {
          var y = ytransform(p, s.y[i]);
          if (y === null || s.x[i] === null) continue;
          if (s.style === "marker") {
            var X = sx(s.x[i]), Y = sy(y);
            el("path", {d: "M" + (X - 6) + " " + Y + "L" + X + " " + (Y - 6) + "L" + (X + 6) + " " + Y + "L" + X + " " +
                        (Y + 6) + "Z", stroke: "#000", "stroke-width": 1}, g);
          } else {
            el("circle", {cx: sx(s.x[i]).toFixed(1), cy: sy(y).toFixed(1), r: r}, g);
          }
        }
      } else {
        el("path", {d: pathOf(s.x, s.y, sx, sy, p), fill: "none", stroke: c, "stroke-width": s.width || 1.3,
                    "stroke-dasharray": s.dash || null, "class": "line"}, data);
      }
    });
    p.sel = el("rect", {x: 0, y: 0, width: 0, height: 0, fill: "#39f", "fill-opacity": 0.15, stroke: "#39f",
                        visibility: "hidden", "class": "selection"}, svg);
  }

  function drawBox(p) {
    var svg = p.svg, w = p.width, h = p.height;
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    var lo = Infinity, hi = -Infinity;
    p.boxes.forEach(function (b) {
      [b.min, b.max, b.p5, b.p95].forEach(function (v) { if (v !== null && isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); } });
    });
    var yr = lo === Infinity ? [0, 1] : pad([lo, hi], 0.06);
    var n = p.boxes.length, pw = (w - M.l - M.r) / Math.max(n, 1);
    var sy = function (y) { return h - M.b - (y - yr[0]) / (yr[1] - yr[0]) * (h - M.t - M.b); };
    el("rect", {x: M.l, y: M.t, width: w - M.l - M.r, height: h - M.t - M.b, fill: "#fff", stroke: "#999"}, svg);
    var axes = el("g", {"font-size": "11", fill: "#333"}, svg);
    niceTicks(yr[0], yr[1], 5).forEach(function (v) {
      el("line", {x1: M.l, x2: w - M.r, y1: sy(v), y2: sy(v), stroke: "#eee"}, axes);
      el("text", {x: M.l - 4, y: sy(v) + 4, "text-anchor": "end"}, axes).textContent = fmt(v);
    });
    el("text", {x: 14, y: (M.t + h - M.b) / 2, "text-anchor": "middle",
                transform: "rotate(-90 14 " + ((M.t + h - M.b) / 2) + ")"}, axes).textContent = p.ylabel || "";
    p.boxes.forEach(function (b, k) {
      var cx = M.l + pw * (k + 0.5), bw = Math.min(40, pw * 0.5), c = COLORS[k % COLORS.length];
      var g = el("g", {"class": "box"}, svg);
      if (b.p5 === null || b.p95 === null) return;
      el("line", {x1: cx, x2: cx, y1: sy(b.p5), y2: sy(b.p95), stroke: "#555"}, g);
      el("rect", {x: cx - bw / 2, y: sy(b.p75), width: bw, height: Math.max(1, sy(b.p25) - sy(b.p75)),
                  fill: c, "fill-opacity": 0.35, stroke: c}, g);
      el("line", {x1: cx - bw / 2, x2: cx + bw / 2, y1: sy(b.p50), y2: sy(b.p50), stroke: "#000", "stroke-width": 2}, g);
      [b.min, b.max].forEach(function (v) { if (v !== null) el("circle", {cx: cx, cy: sy(v), r: 2.5, fill: "#555"}, g); });
      var t = el("text", {x: cx, y: h - M.b + 14, "text-anchor": "middle"}, axes);
      t.textContent = b.name.length > 22 ? b.name.slice(0, 21) + "\u2026" : b.name;
      el("title", {}, t).textContent = b.name;
    });
  }

  function setX(p, a, b, propagate) {
    p.xr = [a, b];
    if (p.kind === "line") p.yr = yrangeOf(p, a, b);
    draw(p);
    if (propagate && p.group && groups[p.group]) {
      groups[p.group].forEach(function (q) { if (q !== p) setX(q, a, b, false); });
    }
  }
  function reset(p, propagate) {
    var fx = fullX(p);
    if (p.kind === "plan") { p.xr = fx; p.yr = p.fullY; draw(p); return; }
    setX(p, fx[0], fx[1], propagate);
  }

  function attach(p) {
    var svg = p.svg, start = null;
    function pt(ev) {
      var r = svg.getBoundingClientRect();
      return [(ev.clientX - r.left) * p.width / r.width, (ev.clientY - r.top) * p.height / r.height];
    }
    svg.addEventListener("mousedown", function (ev) { start = pt(ev); ev.preventDefault(); });
    svg.addEventListener("mousemove", function (ev) {
      if (!start) return;
      var q = pt(ev);
      var y0 = p.kind === "plan" ? Math.min(start[1], q[1]) : M.t;
      var hh = p.kind === "plan" ? Math.abs(q[1] - start[1]) : p.height - M.t - M.b;
      p.sel.setAttribute("x", Math.min(start[0], q[0]));
      p.sel.setAttribute("y", y0);
      p.sel.setAttribute("width", Math.abs(q[0] - start[0]));
      p.sel.setAttribute("height", hh);
      p.sel.setAttribute("visibility", "visible");
    });
    window.addEventListener("mouseup", function (ev) {
      if (!start) return;
      var q = pt(ev), s = start;
      start = null;
      p.sel.setAttribute("visibility", "hidden");
      if (Math.abs(q[0] - s[0]) < 4) return;
      var inv = function (X) { return p.view.x[0] + (X - M.l) / (p.width - M.l - M.r) * (p.view.x[1] - p.view.x[0]); };
      var a = inv(Math.min(s[0], q[0])), b = inv(Math.max(s[0], q[0]));
      if (p.kind === "plan") {
        if (Math.abs(q[1] - s[1]) < 4) return;
        var invy = function (Y) { return p.view.y[0] + (p.height - M.b - Y) / (p.height - M.t - M.b) * (p.view.y[1] - p.view.y[0]); };
        p.xr = [a, b];
        p.yr = [invy(Math.max(s[1], q[1])), invy(Math.min(s[1], q[1]))];
        draw(p);
      } else {
        setX(p, a, b, true);
      }
    });
    svg.addEventListener("dblclick", function () { reset(p, true); });
  }

  function legend(p, box) {
    var lg = document.createElement("div");
    lg.className = "legend";
    p.series.forEach(function (s) {
      if (s.nolegend) return;
      var item = document.createElement("span");
      item.className = "item";
      var sw = document.createElementNS(NS, "svg");
      sw.setAttribute("width", "26"); sw.setAttribute("height", "10");
      if (s.style === "band" || s.style === "sigma") el("rect", {x: 0, y: 1, width: 26, height: 8, fill: s.color, "fill-opacity": 0.3}, sw);
      else if (s.style === "points" || s.style === "marker") el("circle", {cx: 13, cy: 5, r: 4, fill: s.color}, sw);
      else el("line", {x1: 0, x2: 26, y1: 5, y2: 5, stroke: s.color, "stroke-width": 2, "stroke-dasharray": s.dash || null}, sw);
      item.appendChild(sw);
      item.appendChild(document.createTextNode(" " + s.name));
      item.title = "click to hide or show";
      item.addEventListener("click", function () {
        s.hidden = !s.hidden; item.classList.toggle("off", s.hidden);
        if (p.kind === "line") p.yr = yrangeOf(p, p.xr[0], p.xr[1]);
        draw(p);
      });
      lg.appendChild(item);
    });
    if (p.spans && p.spans.length && p.spanlabel) {
      var it = document.createElement("span");
      it.className = "item";
      it.innerHTML = "<span class=\"spanmark\"></span>";
      it.appendChild(document.createTextNode(" " + p.spanlabel));
      lg.appendChild(it);
    }
    box.appendChild(lg);
  }

  function build(spec) {
    var box = document.getElementById(spec.id);
    if (!box) return;
    var p = spec;
    p.width = W; p.height = p.kind === "plan" ? 520 : (p.height || H);
    var k = 0;
    p.series.forEach(function (s) {
      if (!s.color) { s.color = s.name === "truth" || s.truth ? "#000" : COLORS[(s.ci === undefined ? k++ : s.ci) % COLORS.length]; }
      if (s.dash === undefined && s.style !== "band" && s.style !== "sigma") s.dash = "";
    });
    p.svg = el("svg", {viewBox: "0 0 " + p.width + " " + p.height, width: "100%", "class": "plot " + p.kind,
                       preserveAspectRatio: "xMidYMid meet", role: "img"}, null);
    box.appendChild(p.svg);
    plots[p.id] = p;
    if (p.kind === "box") { drawBox(p); return; }
    legend(p, box);
    if (p.group) (groups[p.group] = groups[p.group] || []).push(p);
    if (p.kind === "plan") {
      var ry = [Infinity, -Infinity];
      p.series.forEach(function (s) { ry = range(s.y, ry[0], ry[1]); });
      p.fullY = ry[0] === Infinity ? [0, 1] : pad(ry, 0.04);
    }
    reset(p, false);
    attach(p);
  }

  function sortable(table) {
    var ths = table.querySelectorAll("tr:first-child th");
    ths.forEach(function (th, col) {
      th.title = "click to sort";
      th.addEventListener("click", function () {
        var asc = th.getAttribute("aria-sort") !== "ascending";
        ths.forEach(function (o) { o.removeAttribute("aria-sort"); });
        th.setAttribute("aria-sort", asc ? "ascending" : "descending");
        var rows = Array.prototype.slice.call(table.querySelectorAll("tr")).slice(1);
        var key = function (r) {
          var c = r.children[col], t = c ? (c.getAttribute("data-v") || c.textContent.trim()) : "";
          var v = parseFloat(t);
          return (t !== "" && isFinite(v) && /^[-+0-9.eE]+$/.test(t)) ? [0, v] : [t === "" ? 2 : 1, t];
        };
        rows.sort(function (a, b) {
          var ka = key(a), kb = key(b);
          if (ka[0] !== kb[0]) return ka[0] - kb[0];
          var c = ka[1] < kb[1] ? -1 : ka[1] > kb[1] ? 1 : 0;
          return asc ? c : -c;
        });
        var parent = rows.length ? rows[0].parentNode : null;
        rows.forEach(function (r) { parent.appendChild(r); });
      });
    });
  }

  if (typeof document === "undefined") {          // loaded by node (tests/test_report_html.py): the helpers only
    module.exports = {logTicks: logTicks, niceTicks: niceTicks, fmt: fmt};
    return;
  }
  var node = document.getElementById("sins-data");
  var data = node ? JSON.parse(node.textContent) : {plots: []};
  data.plots.forEach(build);
  document.querySelectorAll("table.sortable").forEach(sortable);
  window.sinsPlots = {
    plots: plots,
    count: function () { return Object.keys(plots).length; },
    setX: function (id, a, b) { setX(plots[id], a, b, true); },
    view: function (id) { return plots[id].view; }
  };
})();
