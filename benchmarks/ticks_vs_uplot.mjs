// The tick measurement of docs/compare.md ("The plotting script against uPlot"): report.js's niceTicks/fmt
// against uPlot's default number axis.  Run: cd /tmp && npm pack uplot@1.6.32 && tar xzf uplot-1.6.32.tgz &&
//   cp package/dist/uPlot.esm.js up.mjs && echo "export { findIncr, numIncrs, fixedDec, roundDec };" >> up.mjs &&
//   cp REPO/benchmarks/ticks_vs_uplot.mjs . && export REPORT_JS=REPO/sinscli/report/assets/report.js &&
//   for c in 0 1 2 3 4; do CLS=$c N=1000 node ticks_vs_uplot.mjs | head -2; done
// Classes (CLS): 0 near zero, 1 offset by up to 10 spans, 2 by up to 1e4 spans, 3 at 1.7e9, 4 by up to 500 spans.
import fs from "fs";
import * as U from "./up.mjs";
const src = fs.readFileSync(process.env.REPORT_JS || new URL("../sinscli/report/assets/report.js", import.meta.url).pathname, "utf8");
const grab = (name) => { const i = src.indexOf(`  function ${name}(`); const j = src.indexOf("\n  }\n", i); return src.slice(i, j + 4); };
const R = new Function(grab("fmt") + grab("niceTicks").replace("v += step) out.push(Math.abs(v) < step * 1e-9 ? 0 : v);", "v += step) { if (out.length > 1000) throw new Error('runaway'); out.push(Math.abs(v) < step * 1e-9 ? 0 : v); }") + "return {fmt, niceTicks};")();
// uPlot's default number axis: splits of findIncr over numIncrs (dim px, minimum space 50 px for x, 30 for y), labels by
// its default formatter (Intl.NumberFormat, en-US)
const fmtNum = new Intl.NumberFormat("en-US").format;
function uTicks(a, b, dim, space) {
  const [incr] = U.findIncr(a, b, U.numIncrs, dim, space);
  if (!(incr > 0) || (b - a) / incr > 1000 || a + incr === a) throw new Error("no increment");
  // numAxisSplits, with a cap on the loop (its roundDec can stall far from 0)
  const numDec = U.fixedDec.get(incr) || 0, out = [];
  for (let v = U.roundDec(Math.ceil(a / incr) * incr, numDec); v <= b; ) {
    out.push(Object.is(v, -0) ? 0 : v);
    const nx = U.roundDec(v + incr, numDec);
    if (nx <= v || out.length > 1000) throw new Error("stalls");
    v = nx;
  }
  return out;
}
function check(ticks, labels, a, b) {
  const bad = [];
  if (ticks.some(v => v < a - 1e-9 * Math.abs(b - a) || v > b + 1e-9 * Math.abs(b - a))) bad.push("outside");
  if (new Set(labels).size !== labels.length) bad.push("duplicate labels");
  const st = ticks.slice(1).map((v, i) => v - ticks[i]);
  if (st.length && Math.max(...st) - Math.min(...st) > 1e-6 * Math.abs(st[0])) bad.push("uneven");
  // labels exact: a label read back equals the tick to 1e-9 of the step
  if (st.length && labels.some((l, i) => !(Math.abs(Number(l.replace(/,/g, "")) - ticks[i]) <= 1e-6 * st[0]))) bad.push("label != tick");
  return bad;
}
let rng = 7; const rand = () => (rng = (rng * 16807) % 2147483647) / 2147483647;
const cases = [];
for (let k = 0; k < (+process.env.N || 2000); k++) {
  const span = Math.pow(10, -6 + 12 * rand()), cls = +(process.env.CLS ?? -1), kk = cls >= 0 ? cls : k % 5,
        off = [0, 1, 1e3, 1.7e9, -50][kk] * (kk == 3 ? 1 : span * 10 * rand());
  const a = off + (rand() - 0.5) * span, b = a + span;
  cases.push([a, b]);
}
const stats = { report: { n: [], bad: {} }, uplot: { n: [], bad: {} } };
for (const [a, b] of cases) {
  let rt, rl;
  try { rt = R.niceTicks(a, b, 8); rl = rt.map(R.fmt); } catch (e) { stats.report.bad["never ends (v += step below one ulp)"] = (stats.report.bad["never ends (v += step below one ulp)"] || 0) + 1; rt = []; rl = []; }
  let ut, ul;
  try { ut = uTicks(a, b, 800, 50); ul = ut.map(fmtNum); } catch (e) { stats.uplot.bad["no ticks (no increment fits)"] = (stats.uplot.bad["no ticks (no increment fits)"] || 0) + 1; ut = []; ul = []; }
  for (const [name, t, l] of [["report", rt, rl], ["uplot", ut, ul]]) {
    if (!t.length) continue;
    stats[name].n.push(t.length);
    for (const p of check(t, l, a, b)) stats[name].bad[p] = (stats[name].bad[p] || 0) + 1;
  }
}
for (const name of ["report", "uplot"]) {
  const n = stats[name].n.sort((x, y) => x - y);
  console.log(name, "ticks per axis min/median/max", n[0], n[n.length >> 1], n[n.length - 1], "problems", JSON.stringify(stats[name].bad));
}
// examples
for (const [a, b] of [[0, 1], [0, 0.3], [1.7e9, 1.7e9 + 10], [-0.0021, 0.0013], [0, 123456]]) {
  console.log(`[${a}, ${b}] report:`, R.niceTicks(a, b, 8).map(R.fmt).join(" "), "| uplot:", uTicks(a, b, 800, 50).map(fmtNum).join(" "));
}
