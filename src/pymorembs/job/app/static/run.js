// Run the job (a child process on the server), its progress, Cancel, and saving the job file.
import { $, api, fail } from "./api.js";
import { loadResults } from "./results.js";

// ---- run --------------------------------------------------------------------------------------
$("run").onclick = async () => {
  try {
    await api("/api/run", {});
    $("cancel").disabled = false; $("run").disabled = true;
    poll();
  } catch (e) { fail(e); }
};
$("cancel").onclick = async () => { await api("/api/cancel", {}); };
async function poll() {
  const s = await api("/api/status");
  $("progress").value = s.fraction || 0;
  $("stage").textContent = s.state === "running" ? s.stage : s.state + (s.error ? `: ${s.error}` : "");
  $("stage").dataset.state = s.state;
  $("log").textContent = (s.lines || []).join("\n");
  if (s.state === "running") { setTimeout(poll, 300); return; }
  $("cancel").disabled = true; $("run").disabled = false;
  if (s.state === "done") loadResults();
}
$("save").onclick = async () => {
  try {
    const saved = await api("/api/save", { path: $("save-path").value });
    $("saved").textContent = `saved ${saved.path}`; $("saved").dataset.path = saved.path;
  } catch (e) { $("saved").textContent = e.message; }
};
