// pushtrain table page (sweeps, atlas): a summary, pictures, and a table of runs whose rows
// can be clicked to see one run. Plain JavaScript, no dependencies.
"use strict";
(function () {
  const D = JSON.parse(document.getElementById("report-data").textContent);
  const $ = (id) => document.getElementById(id);
  $("title").textContent = D.title;
  $("message").textContent = D.message || "";
  const fmt = (x) => (x === null || x === undefined ? "" : typeof x === "number" &&
                      !Number.isInteger(x) ? x.toPrecision(4) : String(x));
  function flatten(obj, prefix, out) {
    Object.entries(obj || {}).forEach(([k, v]) => {
      const key = prefix ? `${prefix}.${k}` : k;
      if (v !== null && typeof v === "object" && !Array.isArray(v)) flatten(v, key, out);
      else out.push([key, Array.isArray(v) ? v.map(fmt).join(", ") : fmt(v)]);
    });
    return out;
  }
  function fill(table, pairs) {
    table.textContent = "";
    pairs.forEach(([k, v]) => {
      const tr = document.createElement("tr");
      const th = document.createElement("th"); th.textContent = k;
      const td = document.createElement("td"); td.textContent = v;
      tr.appendChild(th); tr.appendChild(td); table.appendChild(tr);
    });
  }
  fill($("summary"), flatten(D.summary, "", []));
  (D.images || []).forEach((img) => {
    const h = document.createElement("h2"); h.textContent = img.name;
    const el = document.createElement("img"); el.alt = img.name;
    el.src = "data:image/png;base64," + img.png;
    $("images-panel").appendChild(h); $("images-panel").appendChild(el);
  });
  const columns = D.columns || [];
  let order = D.rows.map((_, i) => i), sortBy = null, ascending = true, chosen = null;
  function choose(i) {
    chosen = i;
    fill($("run"), columns.map((c, k) => [c, fmt(D.rows[i][k])]));
    Array.from(document.querySelectorAll("#runs tr.row")).forEach((tr) =>
      tr.classList.toggle("chosen", Number(tr.dataset.index) === i));
  }
  function render() {
    const table = $("runs");
    table.textContent = "";
    const head = document.createElement("tr");
    columns.forEach((c, k) => {
      const th = document.createElement("th");
      th.textContent = c + (sortBy === k ? (ascending ? " \u25b2" : " \u25bc") : "");
      th.addEventListener("click", () => { ascending = sortBy === k ? !ascending : true;
                                           sortBy = k; sort(); render(); });
      head.appendChild(th);
    });
    table.appendChild(head);
    order.forEach((i) => {
      const tr = document.createElement("tr"); tr.className = "row"; tr.dataset.index = i;
      D.rows[i].forEach((v, k) => {
        const td = document.createElement("td"); td.textContent = fmt(v);
        if (columns[k] === D.fail_column && v) td.className = "fail";
        tr.appendChild(td);
      });
      tr.addEventListener("click", () => choose(i));
      table.appendChild(tr);
    });
    $("runs-title").textContent = `Runs (${D.rows.length})`;
    if (chosen !== null) choose(chosen);
  }
  function sort() {
    const k = sortBy;
    order.sort((a, b) => {
      const x = D.rows[a][k], y = D.rows[b][k];
      if (x === y) return a - b;
      if (x === null || x === "") return 1;
      if (y === null || y === "") return -1;
      const r = typeof x === "number" && typeof y === "number" ? x - y
        : String(x).localeCompare(String(y));
      return ascending ? r : -r;
    });
  }
  render();
  if (D.rows.length) choose(0);
  window.pushtrainReport = {ready: true, choose, state: () => ({chosen, rows: D.rows.length,
    shown: Array.from(document.querySelectorAll("#run tr")).map((tr) =>
      [tr.children[0].textContent, tr.children[1].textContent])})};
})();
