// invr's dashboard: a read-only single-page application over the JSON API of docs/dashboard.md.
// Every name from the server reaches the page as text (textContent, setAttribute), never as
// markup; the server's Content-Security-Policy allows no inline script besides.
"use strict";

const POLL_MS = 1500;
let timer = null;
let view = null;  // the current page's state (charts, event cursors, images shown)
let generation = 0;  // bumped by every page change: work begun for an older page stops at its next step
function current(gen) { return gen === generation; }

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k === "class") e.className = v;
    else if (k === "text") e.textContent = v;
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v === true ? "" : String(v));
  }
  for (const c of children.flat(Infinity)) {
    if (c === null || c === undefined) continue;
    e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return e;
}

function fmt(x, digits = 4) {
  if (x === null || x === undefined || Number.isNaN(x)) return "–";
  if (typeof x !== "number") return String(x);
  if (x !== 0 && (Math.abs(x) < 1e-3 || Math.abs(x) >= 1e5)) return x.toExponential(digits - 1);
  return Number(x.toPrecision(digits)).toString();
}

function duration(s) {
  if (!(s > 0)) return "–";
  if (s < 60) return s.toFixed(1) + " s";
  if (s < 3600) return Math.floor(s / 60) + " min " + Math.round(s % 60) + " s";
  return Math.floor(s / 3600) + " h " + Math.round((s % 3600) / 60) + " min";
}

class AuthError extends Error {}

async function api(path, options) {
  const r = await fetch(path, Object.assign({ credentials: "same-origin", cache: "no-store" }, options || {}));
  if (r.status === 401) throw new AuthError((await r.json().catch(() => ({}))).error || "sign in");
  if (!r.ok) throw new Error((await r.json().catch(() => ({}))).error || r.status + " " + r.statusText);
  return r.json();
}

function jobHref(id) { return "#/job/" + encodeURIComponent(id); }
// An EXR is converted at `ev` stops of exposure (the page's control); PNGs are shown as they are.
function imageUrl(id, name, ev) {
  const url = "/api/jobs/" + encodeURIComponent(id) + "/image?name=" + encodeURIComponent(name);
  return name.endsWith(".exr") && ev ? url + "&exposure=" + ev : url;
}

function setMain(...children) {
  const main = document.getElementById("main");
  main.replaceChildren(...children);
}

function stamp() {
  document.getElementById("updated").textContent = "Updated " + new Date().toLocaleTimeString() + ".";
}

// ---------------------------------------------------------------- sign-in

function showSignIn(message) {
  stop();
  const input = el("input", { type: "password", id: "token", autocomplete: "off", placeholder: "client token" });
  const status = el("p", { id: "signin-error", class: "error" }, message && message !== "sign in" ? message : "");
  const form = el("form", { class: "signin", id: "signin" },
    el("h1", { text: "Sign in" }),
    el("p", { class: "muted", text: "This server checks client tokens. Paste yours: it is sent once and kept by the server, not by the page." }),
    input, el("button", { type: "submit", text: "Sign in" }), status);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    try {
      const r = await fetch("/api/login", { method: "POST", credentials: "same-origin",
        headers: { "Content-Type": "application/json" }, body: JSON.stringify({ token: input.value }) });
      input.value = "";
      if (!r.ok) throw new Error((await r.json().catch(() => ({}))).error || "refused");
      await session();
      route();
    } catch (e) {
      status.textContent = "Refused: " + e.message;
    }
  });
  setMain(form);
  input.focus();
}

async function session() {
  const s = await api("/api/session");
  const out = document.getElementById("signout");
  out.hidden = !(s.auth_required && s.signed_in);
  document.getElementById("who").textContent = s.auth_required && s.signed_in ? "signed in as " + s.name : "";
  return s;
}

document.getElementById("signout").addEventListener("click", async () => {
  await fetch("/api/logout", { method: "POST", credentials: "same-origin", headers: { "Content-Type": "application/json" }, body: "{}" });
  await session();
  showSignIn();
});

// ---------------------------------------------------------------- pages

function stop() {
  ++generation;
  if (timer) clearTimeout(timer);
  timer = null;
  if (view && view.charts) for (const c of view.charts) c.destroy();
  view = null;
}

function schedule(fn, gen) {
  timer = setTimeout(async () => {
    if (!current(gen)) return;
    try {
      await fn();
    } catch (e) {
      if (!current(gen)) return;
      if (e instanceof AuthError) return showSignIn(e.message);
      document.getElementById("updated").textContent = "Update failed: " + e.message;
    }
    if (current(gen)) schedule(fn, gen);
  }, POLL_MS);
}

async function jobsPage(gen) {
  view = { kind: "jobs" };
  const body = el("tbody", { id: "jobs-body" });
  const table = el("table", { id: "jobs" },
    el("thead", {}, el("tr", {}, ["Job", "Name", "State", "Step", "Rate", "ETA", "Priority", "Workers", "Method", "Submitted by", "Submitted", "Loss", "Param. error"].map((h) => el("th", { text: h })))),
    body);
  const count = el("p", { class: "muted", id: "jobs-count" });
  setMain(el("h1", { text: "Jobs" }), count, table);
  const refresh = async () => {
    const { jobs } = await api("/api/jobs");
    if (!current(gen)) return;
    jobs.sort((a, b) => b.submitted_unix - a.submitted_unix || (a.job_id < b.job_id ? 1 : -1));
    count.textContent = jobs.length + (jobs.length === 1 ? " job" : " jobs") + ", " + jobs.filter((j) => j.state === "RUNNING").length + " running";
    body.replaceChildren(...jobs.map((j) => el("tr", { "data-job": j.job_id },
      el("td", {}, el("a", { href: jobHref(j.job_id), text: j.job_id })),
      el("td", { class: "name", text: j.name }),
      el("td", { class: "state-" + j.state.toLowerCase(), text: j.state.toLowerCase() }),
      el("td", {}, el("progress", { max: Math.max(1, j.steps), value: j.step }), " " + j.step + " / " + j.steps),
      el("td", { class: "num", text: j.steps_per_second > 0 ? fmt(j.steps_per_second, 3) + "/s" : "–" }),
      el("td", { class: "num", text: j.state === "RUNNING" ? duration(j.eta_seconds) : "–" }),
      el("td", { class: "num", text: j.priority }),
      el("td", { class: "num", text: j.workers }),
      el("td", { text: j.method }),
      el("td", { text: j.submitted_by || "–" }),
      el("td", { text: new Date(j.submitted_unix * 1000).toLocaleString() }),
      el("td", { class: "num", text: fmt(j.loss) }),
      el("td", { class: "num", text: j.param_error >= 0 ? fmt(j.param_error) : "–" }))));
    if (!performance.getEntriesByName("invr-jobs-drawn").length) performance.mark("invr-jobs-drawn");  // the load time, for tests
    stamp();
  };
  await refresh();
  schedule(refresh, gen);
}

async function workersPage(gen) {
  view = { kind: "workers" };
  const body = el("tbody", { id: "workers-body" });
  const count = el("p", { class: "muted", id: "workers-count" });
  setMain(el("h1", { text: "Workers" }), count, el("table", { id: "workers" },
    el("thead", {}, el("tr", {}, ["Worker", "Threads", "State", "Current job", "Jobs", "Shards", "Last heard"].map((h) => el("th", { text: h })))), body));
  const refresh = async () => {
    const { workers } = await api("/api/workers");
    if (!current(gen)) return;
    count.textContent = workers.length + " connected, " + workers.filter((w) => w.busy).length + " busy";
    body.replaceChildren(...workers.map((w) => el("tr", {},
      el("td", { class: "name", text: w.name }),
      el("td", { class: "num", text: w.capacity }),
      el("td", { text: w.leaving ? "leaving" : w.busy ? "busy" : "idle" }),
      el("td", {}, w.current_job ? el("a", { href: jobHref(w.current_job), text: w.current_job }) : "–"),
      el("td", {}, w.job_ids.length ? w.job_ids.map((id, i) => [i ? ", " : "", el("a", { href: jobHref(id), text: id })]) : "–"),
      el("td", { class: "num", text: w.shards }),
      el("td", { class: "num", text: fmt(w.seconds_since_heard, 2) + " s ago" }))));
    stamp();
  };
  await refresh();
  schedule(refresh, gen);
}

// The series a job's chart draws, each only when the job has it. The axis is logarithmic: the
// unbiased loss, which may be negative, is drawn as its absolute value (and says so).
const SERIES = [
  ["loss", "|loss| (absolute value of the signed loss)"],
  ["image_loss", "image error (smoothed)"],
  ["param_error", "parameter error"],
  ["shape_error", "shape error"],
];
const COLOURS = ["#2f6fb3", "#d9822b", "#23784a", "#b3261e"];  // by series
const DASHES = [[], [6, 3], [2, 2], [10, 3, 2, 3], [1, 4]];       // by job, when jobs are compared

function makeChart(canvas, xTitle) {
  return new Chart(canvas, {
    type: "line",
    data: { datasets: [] },
    options: {
      animation: false, parsing: false, normalized: true, maintainAspectRatio: false,
      interaction: { mode: "nearest", intersect: false },
      elements: { point: { radius: 0 }, line: { borderWidth: 1.5 } },
      scales: { x: { type: "linear", title: { display: true, text: xTitle } }, y: { type: "logarithmic", title: { display: true, text: "error, |loss| (log scale)" } } },
      plugins: { legend: { position: "bottom" } },
    },
  });
}

// One job's events into its series: read from the event cursor on, appended to the charts.
class JobSeries {
  constructor(id, index) {
    this.id = id;
    this.label = "";
    this.index = index;
    this.next = 1;
    this.byTime = {};
    this.bySteps = {};
    this.parameters = null;
    this.messages = [];
    this.final = null;
  }
  async poll() {
    for (;;) {
      const r = await api("/api/jobs/" + encodeURIComponent(this.id) + "/events?from=" + this.next + "&max=1000");
      for (const e of r.events) {
        if (e.step) {
          for (const [key] of SERIES) {
            const v = key === "loss" && typeof e.step[key] === "number" ? Math.abs(e.step[key]) : e.step[key];
            if (typeof v === "number" && v > 0) {
              (this.byTime[key] = this.byTime[key] || []).push({ x: e.step.seconds, y: v });
              (this.bySteps[key] = this.bySteps[key] || []).push({ x: e.step.step, y: v });
            }
          }
          // StepProgress.parameters: [{name, values}], as every JSON of invr's messages has it.
          if (e.step.parameters.length)
            this.parameters = { step: e.step.step, values: Object.fromEntries(e.step.parameters.map((p) => [p.name, p.values])) };
        }
        if (e.message) {
          this.messages.push(e.message);
          if (this.messages.length > 50) this.messages.shift();
        }
        if (e.final) this.final = e.final;
      }
      this.next = r.next;
      if (r.events.length < 1000) return;
    }
  }
  datasets(which) {
    const data = which === "time" ? this.byTime : this.bySteps;
    return SERIES.map(([key, name], i) => [key, name, COLOURS[i]]).filter(([key]) => data[key] && data[key].length).map(([key, name, colour]) => ({
      label: (this.label ? this.label + ": " : "") + name,
      data: data[key],
      borderColor: colour,
      backgroundColor: colour,
      borderDash: DASHES[this.index % DASHES.length],
    }));
  }
}

function difference(canvas, a, b) {
  const w = Math.min(a.naturalWidth, b.naturalWidth), h = Math.min(a.naturalHeight, b.naturalHeight);
  if (!w || !h) return false;
  canvas.width = w;
  canvas.height = h;
  const ctx = canvas.getContext("2d");
  const scratch = document.createElement("canvas");
  scratch.width = w;
  scratch.height = h;
  const sc = scratch.getContext("2d");
  sc.drawImage(a, 0, 0);
  const pa = sc.getImageData(0, 0, w, h).data;
  sc.drawImage(b, 0, 0);
  const pb = sc.getImageData(0, 0, w, h).data;
  const out = ctx.createImageData(w, h);
  for (let i = 0; i < pa.length; i += 4) {
    for (let c = 0; c < 3; ++c) out.data[i + c] = Math.min(255, 4 * Math.abs(pa[i + c] - pb[i + c]));
    out.data[i + 3] = 255;
  }
  ctx.putImageData(out, 0, 0);
  canvas.dataset.ready = "1";
  return true;
}

function loadImage(img, src) {
  return new Promise((resolve) => {
    if (img.getAttribute("src") === src && img.complete) return resolve(img.naturalWidth > 0);
    img.onload = () => resolve(true);
    img.onerror = () => resolve(false);
    img.setAttribute("src", src);
  });
}

async function jobPage(id, compare, gen) {
  const mine = { kind: "job", id, charts: [], series: [], shown: {} };
  view = mine;
  const title = el("h1", { id: "job-title" });
  const summary = el("div", { class: "summary", id: "job-summary" });
  const timeCanvas = el("canvas", { id: "chart-time" });
  const stepCanvas = el("canvas", { id: "chart-steps" });
  const params = el("tbody", { id: "parameters-body" });
  const textures = el("div", { class: "textures", id: "textures" });
  const views = el("div", { class: "views", id: "views" });
  const log = el("ul", { class: "log", id: "log" });
  const picker = el("select", { id: "compare" }, el("option", { value: "", text: "compare with another job…" }));
  // Exposure in stops for every HDR view (target, snapshot or final render, and their difference):
  // automatic from the first target's percentiles until the user moves it.
  mine.exposure = { ev: 0, auto: true, computed: false };
  const evInput = el("input", { type: "range", id: "exposure", min: "-16", max: "16", step: "0.5", value: "0" });
  const evValue = el("span", { id: "exposure-value", text: "0" });
  const evAuto = el("button", { type: "button", id: "exposure-auto", text: "auto" });
  const setEv = (ev) => {
    mine.exposure.ev = Math.round(ev * 2) / 2;
    evInput.value = String(mine.exposure.ev);
    evValue.textContent = (mine.exposure.ev > 0 ? "+" : "") + mine.exposure.ev + " stops" + (mine.exposure.auto ? " (auto)" : "");
  };
  mine.setExposure = setEv;
  evInput.addEventListener("input", () => {
    mine.exposure.auto = false;
    setEv(Number(evInput.value));
    refreshImages();
  });
  evAuto.addEventListener("click", () => {
    mine.exposure.auto = true;
    mine.exposure.computed = false;
    refreshImages();
  });
  let refreshImages = () => {};
  setMain(title, summary,
    el("div", {}, picker),
    el("div", { class: "charts" }, el("div", { class: "chart" }, timeCanvas), el("div", { class: "chart" }, stepCanvas)),
    el("h2", { text: "Views: target, latest snapshot, difference (×4), at one exposure" }),
    el("div", { class: "exposure" }, el("label", { for: "exposure", text: "Exposure " }), evInput, " ", evValue, " ", evAuto), views,
    el("h2", { text: "Parameters" }), el("table", { id: "parameters" }, el("thead", {}, el("tr", {}, el("th", { text: "Name" }), el("th", { text: "Values" }))), params),
    textures,
    el("h2", { text: "Log" }), log);
  mine.charts = [makeChart(timeCanvas, "seconds"), makeChart(stepCanvas, "step")];
  const others = (compare || []).filter((c) => c && c !== id);
  picker.addEventListener("change", () => {
    if (picker.value) location.hash = jobHref(id) + "?compare=" + [...others, picker.value].map(encodeURIComponent).join(",");
  });
  const all = [id, ...others];
  mine.series = all.map((j, i) => new JobSeries(j, i));

  const refresh = async () => {
    const status = await api("/api/jobs/" + encodeURIComponent(id));
    if (!current(gen)) return;
    for (const s of mine.series) await s.poll();
    if (!current(gen)) return;
    const labels = mine.series.length > 1;
    for (const s of mine.series) s.label = labels ? s.id + " " + (s.id === id ? status.method : "") : "";
    if (labels) {
      const { jobs } = await api("/api/jobs");
      if (!current(gen)) return;
      for (const s of mine.series) {
        const j = jobs.find((x) => x.job_id === s.id);
        if (j) s.label = s.id + " " + j.method;
      }
      if (picker.options.length === 1) for (const j of jobs) if (!all.includes(j.job_id)) picker.append(el("option", { value: j.job_id, text: j.job_id + " " + j.name }));
    } else if (picker.options.length === 1) {
      const { jobs } = await api("/api/jobs");
      if (!current(gen)) return;
      for (const j of jobs) if (j.job_id !== id) picker.append(el("option", { value: j.job_id, text: j.job_id + " " + j.name }));
    }
    title.textContent = (status.name || id) + " (" + id + ")";
    summary.replaceChildren(
      ...[["state", status.state.toLowerCase()], ["step", status.step + " / " + status.steps], ["method", status.method],
        ["rate", status.steps_per_second > 0 ? fmt(status.steps_per_second, 3) + " steps/s" : "–"],
        ["ETA", status.state === "RUNNING" ? duration(status.eta_seconds) : "–"], ["loss", fmt(status.loss)],
        ["parameter error", status.param_error >= 0 ? fmt(status.param_error) : "–"], ["time", duration(status.seconds)],
        ["workers", status.workers], ["submitted by", status.submitted_by || "–"]]
        .map(([k, v]) => el("span", {}, el("b", { text: k + ": " }), String(v))),
      ...(status.reason ? [el("span", { class: "error", text: status.reason })] : []));
    for (const [chart, which] of [[mine.charts[0], "time"], [mine.charts[1], "steps"]]) {
      chart.data.datasets = mine.series.flatMap((s) => s.datasets(which));
      chart.update("none");
      chart.canvas.dataset.points = String(chart.data.datasets.reduce((n, d) => n + d.data.length, 0));
    }
    const own = mine.series[0];
    if (!own.parameters && finishedState(status.state) && status.results.includes("parameters.json") && !mine.finalParameters) {
      // A finished job's values (its events may predate the parameters they carry): the results'.
      const values = await api("/api/jobs/" + encodeURIComponent(id) + "/file?name=parameters.json").catch(() => null);
      if (!current(gen)) return;
      if (values) {
        const scalars = Object.entries(values).filter(([, v]) => Array.isArray(v) || typeof v === "number");
        mine.finalParameters = { step: status.step, values: Object.fromEntries(scalars.map(([k, v]) => [k, Array.isArray(v) ? v : [v]])) };
      }
    }
    if (!own.parameters && mine.finalParameters) own.parameters = mine.finalParameters;
    if (own.parameters) {
      params.replaceChildren(...Object.entries(own.parameters.values).map(([name, values]) =>
        el("tr", {}, el("td", { text: name }), el("td", { class: "num", text: values.map((v) => fmt(v, 4)).join("  ") }))));
    } else if (!params.children.length) {
      params.replaceChildren(el("tr", {}, el("td", { class: "muted", text: "no scalar or small parameters reported yet (textures are shown below)" }), el("td")));
    }
    log.replaceChildren(...own.messages.slice(-20).map((m) => el("li", { text: m })));
    refreshImages = () => showImages(mine, status, views, textures, gen);
    await showImages(mine, status, views, textures, gen);
    if (current(gen)) stamp();
  };
  await refresh();
  schedule(refresh, gen);
}

async function showImages(mine, status, views, textures, gen) {
  const id = status.job_id;
  // The automatic exposure: from the first view's target, once it exists (the user's choice stays).
  const first = status.images.views.find((v) => v.target_hdr);
  if (mine.exposure.auto && !mine.exposure.computed && first) {
    const r = await api("/api/jobs/" + encodeURIComponent(id) + "/exposure?name=" + encodeURIComponent(first.target_hdr)).catch(() => null);
    if (!current(gen)) return;
    if (r) {
      mine.exposure.computed = true;
      mine.setExposure(r.ev);
    }
  }
  const ev = mine.exposure.ev;
  const texKey = JSON.stringify(status.images.textures);
  if (mine.shown.textures !== texKey) {
    mine.shown.textures = texKey;
    const when = finishedState(status.state) ? "result" : "step " + status.images.snapshot_step;
    textures.replaceChildren(...status.images.textures.map((t) =>
      el("div", { class: "texture" },
        t.truth ? el("figure", {}, el("img", { src: imageUrl(id, t.truth), alt: t.parameter + " truth" }), el("figcaption", { text: t.parameter + " (truth)" })) : null,
        el("figure", {}, el("img", { src: imageUrl(id, t.file), alt: t.parameter }), el("figcaption", { text: t.parameter + " (" + when + ")" })))));
  }
  if (!status.images.views.length && !views.children.length)
    views.replaceChildren(el("p", { class: "muted", text: "No snapshot yet: submit with --snapshot-every N to see the renders here while the job runs." }));
  for (const v of status.images.views) {
    if (!current(gen)) return;
    let box = views.querySelector("#view-" + v.view);
    if (!box) {
      if (views.firstChild && !views.firstChild.classList.contains("view")) views.replaceChildren();
      box = el("div", { class: "view", id: "view-" + v.view },
        el("figure", {}, el("img", { id: "target-view" + v.view, alt: "target" }), el("figcaption", { text: "target, view " + v.view })),
        el("figure", {}, el("img", { id: "snapshot-view" + v.view, alt: "snapshot" }), el("figcaption", { id: "snapshot-caption-view" + v.view })),
        el("figure", {}, el("canvas", { id: "diff-view" + v.view }), el("figcaption", { text: "|target − render| × 4, same exposure" })));
      views.append(box);
    }
    const isFinal = !!v.final && finishedState(status.state);
    const latest = isFinal ? v.final_hdr || v.final : v.snapshot_hdr || v.snapshot;
    const target = v.target_hdr || v.target;
    const key = (target || "") + "|" + (latest || "") + "|" + ev;
    if (mine.shown["view" + v.view] === key) continue;
    const t = box.querySelector("#target-view" + v.view), s = box.querySelector("#snapshot-view" + v.view);
    const [okT, okS] = await Promise.all([target ? loadImage(t, imageUrl(id, target, ev)) : false, latest ? loadImage(s, imageUrl(id, latest, ev)) : false]);
    if (!current(gen)) return;
    // Shown once both load; a failed load is tried again at the next poll.
    if ((!target || okT) && (!latest || okS)) mine.shown["view" + v.view] = key;
    box.querySelector("#snapshot-caption-view" + v.view).textContent = !latest ? "no snapshot yet" : isFinal ? "final render" : "snapshot at step " + status.images.snapshot_step;
    if (latest) s.dataset.step = String(isFinal ? status.step : status.images.snapshot_step);
    t.dataset.exposure = s.dataset.exposure = String(ev);
    if (okT && okS) difference(box.querySelector("#diff-view" + v.view), t, s);
  }
}

function finishedState(s) { return s === "SUCCEEDED" || s === "FAILED" || s === "CANCELLED"; }

// ---------------------------------------------------------------- routing

async function route() {
  stop();
  const gen = generation;
  const hash = location.hash || "#/";
  try {
    const s = await session();
    if (!current(gen)) return;
    if (s.auth_required && !s.signed_in) return showSignIn();
    const m = hash.match(/^#\/job\/([^?]+)(?:\?compare=(.*))?$/);
    if (m) return await jobPage(decodeURIComponent(m[1]), m[2] ? m[2].split(",").map(decodeURIComponent) : [], gen);
    if (hash.startsWith("#/workers")) return await workersPage(gen);
    return await jobsPage(gen);
  } catch (e) {
    if (!current(gen)) return;
    if (e instanceof AuthError) return showSignIn(e.message);
    setMain(el("p", { class: "error", id: "page-error", text: e.message }));
  }
}

window.addEventListener("hashchange", route);
window.invrDashboard = { get view() { return view; } };
route();
