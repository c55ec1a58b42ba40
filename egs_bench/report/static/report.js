// egs-bench report: sort tables by a click on a column header, filter rows by the sweep's axes.
// Plain JavaScript, no library, works from file://.
"use strict";

(function () {
  function sortKey(cell) {
    const raw = cell.dataset.sort !== undefined ? cell.dataset.sort : cell.textContent.trim();
    const num = Number(raw);
    return { empty: raw === "", isNum: raw !== "" && Number.isFinite(num), num: num, raw: raw };
  }

  function compare(a, b) {
    if (a.empty || b.empty) return a.empty === b.empty ? 0 : (a.empty ? 1 : -1);
    if (a.isNum && b.isNum) return a.num - b.num;
    return a.raw.localeCompare(b.raw, undefined, { numeric: true });
  }

  function sortBy(table, column, th) {
    const ascending = th.getAttribute("aria-sort") !== "ascending";
    for (const other of table.tHead.rows[0].cells) other.removeAttribute("aria-sort");
    th.setAttribute("aria-sort", ascending ? "ascending" : "descending");
    const body = table.tBodies[0];
    const rows = Array.from(body.rows).map(function (row, index) {
      return { row: row, key: sortKey(row.cells[column]), index: index };
    });
    rows.sort(function (a, b) {
      const c = compare(a.key, b.key);
      // empty cells stay last whatever the direction; ties keep their order
      if (a.key.empty || b.key.empty) return c || a.index - b.index;
      return (ascending ? c : -c) || a.index - b.index;
    });
    for (const item of rows) body.appendChild(item.row);
  }

  for (const table of document.querySelectorAll("table.sortable")) {
    Array.from(table.tHead.rows[0].cells).forEach(function (th, column) {
      th.tabIndex = 0;
      th.title = "sort by this column";
      th.addEventListener("click", function () { sortBy(table, column, th); });
      th.addEventListener("keydown", function (event) {
        if (event.key === "Enter") sortBy(table, column, th);
      });
    });
  }

  const filters = Array.from(document.querySelectorAll("select[data-axis]"));

  function applyFilters() {
    const chosen = {};
    for (const select of filters) if (select.value) chosen[select.dataset.axis] = select.value;
    for (const row of document.querySelectorAll("table.filterable tbody tr")) {
      let shown = true;
      for (const axis in chosen) {
        const value = row.dataset[axis];
        if (value !== undefined && value !== chosen[axis]) shown = false;
      }
      row.hidden = !shown;
    }
    // leaderboard columns of other sequences
    for (const cell of document.querySelectorAll("table.filterable [data-group]")) {
      cell.hidden = chosen.sequence !== undefined && cell.dataset.group !== chosen.sequence;
    }
  }

  for (const select of filters) select.addEventListener("change", applyFilters);
})();
