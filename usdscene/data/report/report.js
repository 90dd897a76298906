// usdscene report: a static page over data/index.js (every image's frame, camera and label
// codes, loaded at once) and data/labels_<k>.js (full labels of a page of images, loaded when one
// of its images is opened). Both are scripts because browsers refuse fetch() of file:// URLs.
"use strict";
(function () {
  const OVERLAYS = ["box", "amodal", "polygon", "tint", "keypoints", "track", "text"];
  const ROWS_PER_PAGE = 12;
  const SVG = "http://www.w3.org/2000/svg";
  const S = {
    index: null, pages: {}, waiting: {}, imageAt: null, images: [], rows: [], columns: [],
    page: 0, view: -1, current: -1,
    filter: { cls: "", cam: "", frameMin: null, frameMax: null, visMin: 0, visMax: 1 },
  };
  const $ = (id) => document.getElementById(id);

  window.usdsceneReportIndex = function (index) {
    S.index = index;
    start();
  };
  window.usdsceneReportPage = function (k, entries) {
    S.pages[k] = entries;
    (S.waiting[k] || []).forEach((done) => done());
    delete S.waiting[k];
  };

  function pad6(n) { return String(n).padStart(6, "0"); }
  function classColour(k) { return `hsl(${Math.round((k * 137.508) % 360)}, 80%, 58%)`; }
  function decode(code) {
    const bins = S.index.histogramBins;
    const rest = code >> 1;
    return { visible: code & 1, cls: Math.floor(rest / (bins + 1)), bin: rest % (bins + 1) };
  }

  function start() {
    const ix = S.index;
    const nCams = ix.cameras.length;
    S.imageAt = new Int32Array(ix.frames.length * nCams).fill(-1);
    for (let i = 0; i < ix.frame.length; i++) S.imageAt[ix.frame[i] * nCams + ix.camera[i]] = i;
    $("title").textContent = ix.title + " · " + ix.frame.length + " images";
    document.title = ix.title + " · usdscene report";
    if (ix.note) { $("note").textContent = ix.note; $("note").hidden = false; }
    const clsSel = $("f-class"), camSel = $("f-camera");
    ix.classes.forEach((c, k) => clsSel.add(new Option(c, String(k))));
    ix.cameras.forEach((c, k) => camSel.add(new Option(c, String(k))));
    if (ix.frames.length) {
      $("f-frame-min").value = ix.frames[0];
      $("f-frame-max").value = ix.frames[ix.frames.length - 1];
    }
    for (const el of $("filters").querySelectorAll("select, input")) el.addEventListener("change", readFilters);
    $("f-reset").addEventListener("click", resetFilters);
    $("page-prev").addEventListener("click", () => turnPage(-1));
    $("page-next").addEventListener("click", () => turnPage(1));
    $("grid").addEventListener("click", (event) => {
      const cell = event.target.closest(".cell");
      if (cell && cell.dataset.i !== undefined) openImage(Number(cell.dataset.i));
    });
    for (const box of document.querySelectorAll("#viewer-bar input[data-overlay]")) {
      box.addEventListener("change", applyOverlays);
    }
    $("viewer-close").addEventListener("click", closeImage);
    document.addEventListener("keydown", onKey);
    showPictures();
    readFilters();
    applyOverlays();
    document.body.dataset.ready = "1";
    window.usdsceneReadyMs = performance.now();
  }

  function readFilters() {
    const f = S.filter;
    f.cls = $("f-class").value;
    f.cam = $("f-camera").value;
    const number = (id, fallback) => {
      const v = parseFloat($(id).value);
      return Number.isFinite(v) ? v : fallback;
    };
    f.frameMin = number("f-frame-min", -Infinity);
    f.frameMax = number("f-frame-max", Infinity);
    f.visMin = number("f-vis-min", 0);
    f.visMax = number("f-vis-max", 1);
    S.page = 0;
    refresh();
  }

  function resetFilters() {
    $("filters").reset();
    const frames = S.index.frames;
    if (frames.length) {
      $("f-frame-min").value = frames[0];
      $("f-frame-max").value = frames[frames.length - 1];
    }
    readFilters();
  }

  function labelFilterActive() {
    const f = S.filter;
    return f.cls !== "" || f.visMin > 0 || f.visMax < 1;
  }

  // A label passes on its class and its visibility bin (the grid knows fractions to 0.1).
  function labelPasses(d) {
    const f = S.filter, bins = S.index.histogramBins;
    if (f.cls !== "" && d.cls !== Number(f.cls)) return false;
    if (f.visMin <= 0 && f.visMax >= 1) return true;
    if (d.bin === bins) return false;
    const low = d.bin / bins, high = (d.bin + 1) / bins;
    return high > f.visMin && low <= f.visMax;
  }

  // Exact test for a label whose fraction is known (the image view).
  function fullLabelPasses(o) {
    const f = S.filter;
    if (f.cls !== "" && o.k !== Number(f.cls)) return false;
    if (f.visMin <= 0 && f.visMax >= 1) return true;
    return o.v !== null && o.v >= f.visMin && o.v <= f.visMax;
  }

  function imagePasses(i) {
    const ix = S.index, f = S.filter;
    if (f.cam !== "" && ix.camera[i] !== Number(f.cam)) return false;
    const frame = ix.frames[ix.frame[i]];
    if (frame < f.frameMin || frame > f.frameMax) return false;
    if (!labelFilterActive()) return true;
    return ix.codes[i].some((c) => labelPasses(decode(c)));
  }

  function refresh() {
    const ix = S.index;
    S.images = [];
    for (let i = 0; i < ix.frame.length; i++) if (imagePasses(i)) S.images.push(i);
    const frameSet = new Set(S.images.map((i) => ix.frame[i]));
    S.rows = [...frameSet].sort((a, b) => a - b);
    S.columns = S.filter.cam === "" ? ix.cameras.map((_, k) => k) : [Number(S.filter.cam)];
    $("f-count").textContent = `${S.images.length} of ${ix.frame.length} images match`;
    drawStats();
    drawGrid();
  }

  function pageCount() { return Math.max(1, Math.ceil(S.rows.length / ROWS_PER_PAGE)); }

  function turnPage(step) {
    const page = Math.min(pageCount() - 1, Math.max(0, S.page + step));
    if (page !== S.page) { S.page = page; drawGrid(); }
  }

  function thumbSource(i) {
    const ix = S.index, cam = ix.cameras[ix.camera[i]], frame = pad6(ix.frames[ix.frame[i]]);
    if (ix.thumb[i] === 1) return `thumbs/${cam}/${frame}.jpg`;
    if (ix.thumb[i] === 2) return `${ix.imageRoot}/images/${cam}/${frame}.png`;
    return null;
  }

  function drawGrid() {
    const ix = S.index;
    const head = $("grid").tHead, body = $("grid").tBodies[0];
    head.innerHTML = "";
    body.innerHTML = "";
    const hr = head.insertRow();
    hr.appendChild(document.createElement("th")).textContent = "frame";
    for (const c of S.columns) hr.appendChild(document.createElement("th")).textContent = ix.cameras[c];
    const first = S.page * ROWS_PER_PAGE;
    const passing = new Set(S.images);
    const nCams = ix.cameras.length;
    for (const fi of S.rows.slice(first, first + ROWS_PER_PAGE)) {
      const row = body.insertRow();
      const th = row.insertCell();
      th.className = "frame";
      th.textContent = ix.frames[fi];
      for (const c of S.columns) {
        const td = row.insertCell();
        const i = S.imageAt[fi * nCams + c];
        if (i < 0) continue;
        if (!passing.has(i)) td.className = "filtered";
        const cell = document.createElement("a");
        cell.className = "cell";
        cell.tabIndex = 0;
        cell.dataset.i = i;
        cell.title = `${ix.cameras[c]} · frame ${ix.frames[fi]}`;
        if (i === S.current) cell.classList.add("current");
        const src = thumbSource(i);
        if (src) {
          const img = document.createElement("img");
          img.loading = "lazy";
          img.alt = cell.title;
          img.src = src;
          if (ix.thumb[i] === 2) img.className = "small";
          cell.appendChild(img);
        } else {
          cell.classList.add("missing");
        }
        const badge = document.createElement("span");
        badge.className = "badge";
        if (ix.labelled[i]) {
          badge.textContent = ix.codes[i].filter((code) => code & 1).length;
        } else {
          badge.textContent = "no labels yet";
          cell.classList.add("unlabelled");
        }
        cell.appendChild(badge);
        td.appendChild(cell);
      }
    }
    $("page-text").textContent = `rows ${S.rows.length ? first + 1 : 0}–${Math.min(first + ROWS_PER_PAGE, S.rows.length)} of ${S.rows.length} frames · page ${S.page + 1} of ${pageCount()}`;
  }

  function barRows(target, names, values, colour) {
    target.innerHTML = "";
    const top = Math.max(1, ...values);
    names.forEach((name, k) => {
      const row = document.createElement("div");
      row.className = "bar-row";
      const label = document.createElement("span");
      label.className = "name";
      label.textContent = name;
      label.title = name;
      const bar = document.createElement("span");
      bar.className = "bar";
      bar.style.width = `${Math.round((160 * values[k]) / top)}px`;
      if (colour) bar.style.background = colour(k);
      const value = document.createElement("span");
      value.className = "value";
      value.textContent = values[k];
      row.append(label, bar, value);
      target.appendChild(row);
    });
  }

  function drawStats() {
    const ix = S.index, bins = ix.histogramBins;
    const perCamera = ix.cameras.map(() => ({ images: 0, visible: 0, hidden: 0 }));
    const histogram = new Array(bins + 1).fill(0);
    const perClass = new Array(ix.classes.length).fill(0);
    const active = labelFilterActive();
    for (const i of S.images) {
      const cam = perCamera[ix.camera[i]];
      cam.images++;
      for (const code of ix.codes[i]) {
        const d = decode(code);
        if (active && !labelPasses(d)) continue;
        if (d.visible) { cam.visible++; perClass[d.cls]++; } else { cam.hidden++; }
        histogram[d.bin]++;
      }
    }
    const body = $("camera-counts").tBodies[0];
    body.innerHTML = "";
    ix.cameras.forEach((name, k) => {
      const c = perCamera[k];
      if (!c.images) return;
      const row = body.insertRow();
      for (const v of [name, c.images, c.visible, c.hidden]) row.insertCell().textContent = v;
    });
    const names = [];
    for (let b = 0; b < bins; b++) names.push(`${(b / bins).toFixed(1)}–${((b + 1) / bins).toFixed(1)}`);
    const values = histogram.slice(0, bins);
    if (histogram[bins]) { names.push("unknown"); values.push(histogram[bins]); }
    barRows($("histogram"), names, values, null);
    barRows($("class-counts"), ix.classes, perClass, classColour);
  }

  function showPictures() {
    const box = $("pictures"), pictures = S.index.pictures || {};
    const titles = { balance: "balance of the generated document", coverage: "coverage map of the camera plan" };
    for (const key of ["balance", "coverage"]) {
      if (!pictures[key]) continue;
      const h = document.createElement("h2");
      h.textContent = titles[key];
      const img = document.createElement("img");
      img.src = pictures[key];
      img.alt = titles[key];
      img.id = `picture-${key}`;
      const link = document.createElement("a");  // full size in a tab of its own
      link.href = pictures[key];
      link.target = "_blank";
      link.appendChild(img);
      box.append(h, link);
    }
  }

  // ---- image view -------------------------------------------------------------------------

  function withPage(i, done) {
    const k = Math.floor(i / S.index.pageImages);
    if (S.pages[k]) { done(S.pages[k][i % S.index.pageImages]); return; }
    const call = () => done(S.pages[k][i % S.index.pageImages]);
    if (S.waiting[k]) { S.waiting[k].push(call); return; }
    S.waiting[k] = [call];
    const script = document.createElement("script");
    script.src = `data/labels_${String(k).padStart(5, "0")}.js`;
    document.head.appendChild(script);
  }

  function openImage(i) {
    S.view = i;
    S.current = i;
    withPage(i, (entry) => { if (S.view === i) drawImage(i, entry); });
  }

  function closeImage() {
    $("viewer").hidden = true;
    const i = S.view;
    S.view = -1;
    // Show the page holding the image last looked at, with its cell focused.
    const row = S.rows.indexOf(S.index.frame[i]);
    if (row >= 0) S.page = Math.floor(row / ROWS_PER_PAGE);
    drawGrid();
    const cell = document.querySelector(`.cell[data-i="${i}"]`);
    if (cell) cell.focus();
  }

  function svgElement(name, attributes, parent) {
    const el = document.createElementNS(SVG, name);
    for (const [k, v] of Object.entries(attributes)) el.setAttribute(k, v);
    if (parent) parent.appendChild(el);
    return el;
  }

  function drawImage(i, entry) {
    const ix = S.index, cam = ix.cameras[ix.camera[i]], frame = ix.frames[ix.frame[i]];
    const w = entry.w || 1, h = entry.h || 1;
    const svg = $("canvas");
    svg.innerHTML = "";
    // Pixel centres at integer coordinates: pixel (0, 0) covers [-0.5, 0.5]².
    svg.setAttribute("viewBox", `-0.5 -0.5 ${w} ${h}`);
    svgElement("image", { class: "photo", href: `${ix.imageRoot}/${entry.uri}`, x: -0.5, y: -0.5, width: w, height: h,
      preserveAspectRatio: "none" }, svg);
    svg.appendChild(tintFilter());
    // A labelled image with no objects has no tint file (its mask is all background).
    if (!ix.labelled[i] || entry.o.length) {
      svgElement("image", { class: "ov-tint", href: `tints/${cam}/${pad6(frame)}.png`, x: -0.5, y: -0.5, width: w,
        height: h, preserveAspectRatio: "none", filter: "url(#tint-colours)" }, svg);
    }
    const fontSize = Math.max(h / 34, 1);
    const list = $("label-list");
    list.innerHTML = "";
    entry.o.forEach((o) => {
      const passes = fullLabelPasses(o);
      const colour = classColour(o.k);
      const g = svgElement("g", { class: passes ? "label" : "label dim", "data-uid": o.u, stroke: colour,
        fill: "none", opacity: passes ? 1 : 0.25 }, svg);
      const stroke = { "vector-effect": "non-scaling-stroke", "stroke-width": 2 };
      if (o.b) svgElement("rect", { class: "ov-box", x: o.b[0] - o.b[2] / 2, y: o.b[1] - o.b[3] / 2, width: o.b[2],
        height: o.b[3], ...stroke }, g);
      if (o.a) svgElement("rect", { class: "ov-amodal", x: o.a[0] - o.a[2] / 2, y: o.a[1] - o.a[3] / 2, width: o.a[2],
        height: o.a[3], "stroke-dasharray": "6 4", ...stroke }, g);
      if (o.p.length) {
        let d = "";
        for (const [points] of o.p) {
          for (let k = 0; k + 1 < points.length; k += 2) d += `${k ? "L" : "M"}${points[k]} ${points[k + 1]}`;
          d += "Z";
        }
        svgElement("path", { class: "ov-polygon", d, fill: colour, "fill-opacity": 0.18, "fill-rule": "evenodd",
          ...stroke, "stroke-width": 1 }, g);
      }
      for (const [joint, x, y, flag] of o.kp || []) {
        if (!flag) continue;
        const dot = svgElement("circle", { class: "ov-keypoints", cx: x, cy: y, r: Math.max(h / 140, 0.6),
          fill: flag === 2 ? colour : "none", ...stroke, "stroke-width": 1.5 }, g);
        svgElement("title", {}, dot).textContent = `${joint} (${flag === 2 ? "visible" : "occluded"})`;
      }
      const anchor = o.b || o.a;
      if (anchor) {
        const top = anchor[1] - anchor[3] / 2, bottom = anchor[1] + anchor[3] / 2;
        // Text runs from the box edge towards the image centre, so that it stays on the image.
        const rightHalf = anchor[0] > w / 2;
        const x = rightHalf ? anchor[0] + anchor[2] / 2 : anchor[0] - anchor[2] / 2;
        const along = { x, "text-anchor": rightHalf ? "end" : "start", "font-size": fontSize, "stroke-width": fontSize / 5 };
        const text = svgElement("text", { class: "ov-text", y: Math.max(top - fontSize * 0.25, fontSize * 0.8), ...along }, g);
        text.textContent = labelText(o, ix);
        const track = svgElement("text", { class: "ov-track", y: Math.min(bottom + fontSize * 0.9, h - 0.5), ...along }, g);
        track.textContent = o.id != null ? `#${o.id}` : `uid ${o.u}`;
      }
      const li = document.createElement("li");
      if (!passes) li.className = "dim";
      li.style.borderLeft = `6px solid ${colour}`;
      li.style.paddingLeft = "4px";
      li.textContent = `${labelText(o, ix)} · ${o.id != null ? "track " + o.id : "uid " + o.u}${o.n ? " (" + o.n + ")" : ""}` +
        `${o.px !== null && o.px !== undefined ? " · " + o.px + " px" : ""}${o.t ? " · truncated" : ""}` +
        `${o.kp && o.kp.length ? " · " + o.kp.length + " keypoints" : ""}`;
      list.appendChild(li);
    });
    if (!entry.o.length) list.innerHTML = ix.labelled[i] ? "<li>no labels</li>" : "<li>not labelled yet</li>";
    $("viewer-title").textContent = `${cam} · frame ${frame} · ${w}×${h} px · image ${S.images.indexOf(i) + 1} of ${S.images.length}`;
    $("viewer").hidden = false;
    applyOverlays();
  }

  // The tints are grey PNGs of colour indices (0 background, 1..255 instances): this filter
  // makes index k the k-th hue, a golden angle from the previous one, and index 0 transparent.
  let tintDefs = null;
  function tintFilter() {
    if (tintDefs) return tintDefs.cloneNode(true);
    const channels = [[], [], []];
    for (let k = 0; k < 256; k++) {
      const hue = (k * 137.508) % 360, f = (n) => { const a = (n + hue / 30) % 12; return 0.5 - 0.5 * Math.max(-1, Math.min(a - 3, 9 - a, 1)); };
      channels[0].push(f(0).toFixed(3)); channels[1].push(f(8).toFixed(3)); channels[2].push(f(4).toFixed(3));
    }
    tintDefs = svgElement("defs", {});
    const filter = svgElement("filter", { id: "tint-colours", "color-interpolation-filters": "sRGB", x: 0, y: 0,
      width: 1, height: 1 }, tintDefs);
    // alpha := 255 · index, i.e. 0 for the background and 1 for any instance
    svgElement("feColorMatrix", { type: "matrix", values: "1 0 0 0 0  0 1 0 0 0  0 0 1 0 0  255 0 0 0 0" }, filter);
    const transfer = svgElement("feComponentTransfer", {}, filter);
    ["feFuncR", "feFuncG", "feFuncB"].forEach((name, c) =>
      svgElement(name, { type: "discrete", tableValues: channels[c].join(" ") }, transfer));
    svgElement("feFuncA", { type: "linear", slope: 0.55 }, transfer);
    return tintDefs.cloneNode(true);
  }

  function labelText(o, ix) {
    const percent = o.v === null ? "" : o.v > 0 && o.v < 0.01 ? "<1%" : `${Math.round(o.v * 100)}%`;
    const vis = o.v === null ? "visibility ?" : o.b ? `${percent} visible` : "fully occluded";
    return `${ix.classes[o.k]} · ${vis}${o.r ? " · " + o.r : ""}`;
  }

  function applyOverlays() {
    const svg = $("canvas");
    for (const box of document.querySelectorAll("#viewer-bar input[data-overlay]")) {
      for (const el of svg.querySelectorAll(`.ov-${box.dataset.overlay}`)) el.style.display = box.checked ? "" : "none";
    }
  }

  // Next image of the same camera (step ±1 in frames) or of the same frame (±1 in cameras),
  // among the images that pass the filters.
  function neighbour(i, dFrame, dCamera) {
    const ix = S.index;
    const candidates = S.images.filter((j) => dFrame ? ix.camera[j] === ix.camera[i] : ix.frame[j] === ix.frame[i]);
    const key = (j) => dFrame ? ix.frame[j] : ix.camera[j];
    const sorted = candidates.sort((a, b) => key(a) - key(b));
    const at = sorted.indexOf(i);
    const next = sorted[at + (dFrame || dCamera)];
    return next === undefined ? i : next;
  }

  function onKey(event) {
    if (event.target.matches("input, select") && event.key !== "Escape") return;
    const viewing = S.view >= 0;
    if (viewing) {
      const moves = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] };
      if (event.key === "Escape") { closeImage(); event.preventDefault(); return; }
      if (moves[event.key]) {
        const next = neighbour(S.view, ...moves[event.key]);
        if (next !== S.view) openImage(next);
        event.preventDefault();
        return;
      }
      const n = Number(event.key);
      if (n >= 1 && n <= OVERLAYS.length) {
        const box = document.querySelector(`#viewer-bar input[data-overlay="${OVERLAYS[n - 1]}"]`);
        box.checked = !box.checked;
        applyOverlays();
        event.preventDefault();
      }
      return;
    }
    const arrows = { ArrowLeft: [0, -1], ArrowRight: [0, 1], ArrowUp: [-1, 0], ArrowDown: [1, 0] };
    if (arrows[event.key] && event.target.classList.contains("cell")) {
      // Move the focus through the grid: rows are frames, columns cameras.
      const td = event.target.closest("td"), tr = td.parentElement;
      const rows = [...tr.parentElement.rows];
      const r = rows.indexOf(tr) + arrows[event.key][0], c = td.cellIndex + arrows[event.key][1];
      const next = rows[r] && rows[r].cells[c] && rows[r].cells[c].querySelector(".cell");
      if (next) next.focus();
      event.preventDefault();
      return;
    }
    if (event.key === "[") { turnPage(-1); event.preventDefault(); }
    else if (event.key === "]") { turnPage(1); event.preventDefault(); }
    else if (event.key === "Enter" && event.target.classList.contains("cell")) {
      openImage(Number(event.target.dataset.i));
      event.preventDefault();
    }
  }
})();
