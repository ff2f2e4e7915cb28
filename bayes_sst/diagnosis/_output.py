"""diagnosis.json, diagnosis.txt and a small self-contained HTML page with embedded PNG figures."""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

from bayes_sst.diagnosis._data import REVERSAL_SIGNALS, STROKE_SIGNALS
from bayes_sst.diagnosis._diagnose import shrink_words


def _turn(options) -> str:
    return ", a pre-sliding turn left out where one is read" if options.presliding is None else ""


# the side views as their SignalOptions set them, so the text cannot go stale
_STROKE = f"{STROKE_SIGNALS.cutoff_multiple:g}f, |v| >= {100 * STROKE_SIGNALS.reversal_band:g} % of peak{_turn(STROKE_SIGNALS)}"
_REVERSAL = (f"{REVERSAL_SIGNALS.cutoff_multiple:g}f, weight 0 below {100 * REVERSAL_SIGNALS.reversal_band:g} % of "
             f"peak speed, 1 above {100 * (REVERSAL_SIGNALS.reversal_band + REVERSAL_SIGNALS.reversal_taper):g} %"
             f"{_turn(REVERSAL_SIGNALS)}")

DIAGNOSIS_JSON = "diagnosis.json"
DIAGNOSIS_TEXT = "diagnosis.txt"
DIAGNOSIS_HTML = "diagnosis.html"
NEGLIGIBLE_EXCESS = 0.05


def rule_words(rule: str, settings: dict) -> str:
    """steps[].rule in words (docs/diagnosis.md, Selection), with the run's thresholds."""
    floor = f"score >= {settings.get('min_score', 15.0):g} nats and "
    return {"score_z": floor + f">= {settings.get('z_select', 2.5):g} se",
            "sign_test": floor + "a sign test over the tests",
            "loss_scaled_z": floor + f">= {settings.get('z_loss', 5.0):g}x the scatter of the tests it makes worse "
                             "(amplitude resolved, residual lowered; a gain held by one test must remove most of "
                             "a visible excess)",
            "explains_most": floor + "removes most of a clear excess",
            "coefficient_z": f"coefficient >= {settings.get('coefficient_z', 4.0):g} sd from zero, best of its "
                             "round; its score is weak by construction",
            "breakaway": "the breakaway check (nothing else found; the score is the Stribeck column's)"}.get(rule, rule)


def selection_rules(data: dict) -> dict[str, str]:
    """{effect: the rule that first took it} from diagnosis.json's steps (not a later check's),
    and "breakaway" for stiction that the breakaway check selected."""
    rules: dict[str, str] = {}
    for step in data.get("steps", []):
        if "chosen" in step:
            rules.setdefault(step["chosen"], step["rule"])
    for r in data["ranking"]:
        if r.get("rule") == "breakaway":
            rules.setdefault(r["name"], "breakaway")
    return rules


def format_diagnosis(data: dict) -> str:
    """A short human-readable account: verdict, where, ranking (kN in the text, SI in the json)."""
    misfit = (data.get("breakaway_check") or {}).get("misfit") or {}
    at_rest = data.get("shrink_basis") == "breakaway" and "force_rms" in misfit
    if at_rest:
        amounts = (f"where the table rests at its reversals: noise floor {data['noise_floor'] / 1e3:.3f} kN, stick-slip "
                   f"misfit before {data['rms_before'] / 1e3:.3f} kN, after {data['rms_after'] / 1e3:.3f} kN (force "
                   f"residual {misfit['force_rms'] / 1e3:.3f} kN against its floor {misfit['force_noise_floor'] / 1e3:.3f} kN)")
    elif data.get("rms_unit", "N") == "N":
        amounts = (f"noise floor {data['noise_floor'] / 1e3:.3f} kN, residual RMS before {data['rms_before'] / 1e3:.3f} kN, "
                   f"after {data['rms_after'] / 1e3:.3f} kN")
    else:  # the oil column's command-to-motion misfit, dimensionless
        amounts = (f"command-to-motion response misfit: noise floor {data['noise_floor']:.3g}, RMS before "
                   f"{data['rms_before']:.3g}, after {data['rms_after']:.3g}")
    removed = shrink_words(data.get("shrink_basis", "residual"), data["shrink"], data.get("residual_shrink"))
    lines = [f"Diagnosis of {data['series']}", data["verdict"], "", f"{amounts}, {removed}",
             "", "where the base model misses (share of the excess over the noise floor):"]
    # `where` locates the force residual; a breakaway finding's figures above are its own
    if at_rest:
        rms, floor = misfit["force_rms"], misfit["force_noise_floor"]
    else:
        rms, floor = data["rms_before"], data["noise_floor"]
    excess = rms ** 2 - floor ** 2
    if excess < NEGLIGIBLE_EXCESS * floor ** 2:
        lines.append(f"  nowhere: the residual is within {100 * NEGLIGIBLE_EXCESS:.0f} % (mean square) of the noise "
                     "floor, so the shares below are of a negligible excess")
    for w in data["where"][:6]:
        extra = f", {100 * w['sample_share']:.0f} % of the samples" if w.get("sample_share") is not None else ""
        lines.append(f"  {100 * w['share']:6.0f} %  {w['region']}{extra}  "
                     f"(mean square {100 * w['excess_ratio']:+.0f} % over its floor)")
    if data.get("coefficient_trends"):
        lines += ["", "fall of each coefficient over the campaign (first to last test, from the per-test values "
                  "of the model without drift):"]
        lines.append("  " + ", ".join(f"{name} {100 * t['rate']:+.1f} +- {100 * t['sd']:.1f} %"
                                      for name, t in data["coefficient_trends"].items()))
    check = data.get("breakaway_check")
    if check:
        lines += ["", f"breakaway check: the force held at rest at each reversal exceeds the kinetic friction by "
                  f"{100 * check['excess']:+.1f} +- {100 * check['excess_se']:.1f} % (z {check['z']:.1f}; "
                  f"{check['tests']} tests, {check['reversals']} reversals; selects stiction from "
                  f"{100 * check['thresholds']['excess']:.0f} % and z {check['thresholds']['z']:g}"
                  + (", unless the resting reversals lag the sweeping ones by over "
                     f"{-check['thresholds']['lagged_lead_z']:g} se" if "lagged_lead_z" in check["thresholds"] else "")
                  + ("" if check.get("used") else ", not used: another effect was selected") + ")"]
        reading = check.get("resting") or {}
        resting, sweeping = reading.get("resting"), reading.get("sweeping")
        thresholds = check.get("thresholds", {})
        if resting and resting.get("excess") is not None and "resting_inertia" in thresholds:
            lead = ""
            if sweeping and reading.get("lead") is not None and reading.get("lead_se"):
                lead = (f", leading the {sweeping['reversals']} it sweeps through by {100 * reading['lead']:+.1f} "
                        f"+- {100 * reading['lead_se']:.1f} % (z {reading['lead'] / reading['lead_se']:.1f})")
            elif not sweeping:
                lead = ", no reversal it sweeps through to compare"
            lines.append(f"  at the {resting['reversals']} reversals where the table rests (Me*|a| under "
                         f"{thresholds['resting_inertia']:g} Fk): {100 * resting['excess']:+.1f} +- "
                         f"{100 * resting['se']:.1f} % (z {resting['z']:.1f}){lead}; selects from "
                         f"{100 * thresholds['resting_excess']:.0f} % at z {thresholds['resting_z']:g} with a lead of "
                         f"{100 * thresholds['resting_lead']:.0f} % at z {thresholds['resting_lead_z']:g}")
        if check.get("selected_by") and check.get("used"):
            lines.append("  stiction selected by the reading over "
                         + ("the resting reversals" if check["selected_by"] == "resting_reversals" else "all reversals"))
    if data.get("notes"):
        lines += ["", "notes (on the data and the findings):"] + [f"  {note}" for note in data["notes"]]
    lines += ["", "candidate effects (score = elpd difference by leave-one-test-out, nats):"]
    rules = selection_rules(data)
    for r in data["ranking"]:
        params = ", ".join(f"{k} {v['mean']:.4g}" for k, v in r["params"].items())
        mark = "*" if r["name"] in data["selected"] else " "
        view = {"stroke": f"  (stroke view: {_STROKE}",
                "reversal": f"  (reversal view: {_REVERSAL}"}.get(r.get("view"), "")
        if view:
            # an effect the side view took only in its second screening
            view += (f"; scored with {', '.join(r['given'])} in its model)" if r.get("given") else ")")
        rule = (f"  [selected: {rule_words(rules[r['name']], data.get('settings', {}))}]"
                if mark == "*" and r["name"] in rules else "")
        lines.append(f" {mark} {r['name']:20s} {r['score']:9.1f} +- {r['score_se']:6.1f}   {params}{view}{rule}"
                     + _aside(r, selected=mark == "*"))
    if data["selected"]:
        lines += ["", "base parameters moved by the selected effect(s): "
                  + ", ".join(f"{k} {100 * v:+.1f} %" if v is not None else f"{k} n/a"
                              for k, v in data["base_shift"].items())]
    return "\n".join(lines)


def _aside(entry: dict, *, selected: bool) -> str:
    """What the ranking line of an unselected effect needs beside its score: that its reading is
    the base model (on its bound), and, for a score not from the force model, what it scores."""
    words = []
    if entry.get("at_bound") and not selected:
        bounds = [p["bound"] for p in entry.get("per_payload", []) if p.get("bound")]
        words.append("on its bound, the base model" + (f": {bounds[0]}" if bounds else ""))
    if entry.get("domain"):
        words.append(f"nats of the {entry['domain']}")
    return f"  ({'; '.join(words)})" if words else ""


def _png(fig) -> str:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90, bbox_inches="tight")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def figures(diagnosis) -> list[tuple[str, str]]:
    """(caption, base64 PNG) pairs: ranking bar chart, residual against cycle phase, where shares."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = diagnosis.to_json()
    out = []
    fig, ax = plt.subplots(figsize=(6, 3))
    names = [r["name"] for r in data["ranking"]]
    scores = [r["score"] for r in data["ranking"]]
    ses = [r["score_se"] for r in data["ranking"]]
    ax.barh(names, scores, xerr=ses, color=["C3" if n in data["selected"] else "C0" for n in names])
    ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel("elpd difference against the base model (nats)")
    ax.invert_yaxis()
    out.append(("Candidate effects ranked (selected in red; bars: +- 1 standard error)", _png(fig)))
    plt.close(fig)

    figs = diagnosis.figures
    if figs:
        fig, ax = plt.subplots(figsize=(6, 3))
        for t, rb, ra in zip(figs["tests"], figs["base"].residuals, figs["final"].residuals):
            phase = (t.kept / t.period_samples) % 1.0
            ax.plot(phase, rb / 1e3, ".", color="C0", ms=2, alpha=0.5)
            if data["selected"]:
                ax.plot(phase, ra / 1e3, ".", color="C3", ms=2, alpha=0.5)
        ax.set_xlabel("cycle phase")
        ax.set_ylabel("residual (kN)")
        out.append(("Residual force against cycle phase: base model (blue)"
                    + (", with the selected effect(s) (red)" if data["selected"] else "")
                    + "; samples slower than 10 % of the peak speed are outside the likelihood", _png(fig)))
        plt.close(fig)
        reversal = figs.get("views", {}).get("reversal")
        if reversal:
            fig, ax = plt.subplots(figsize=(6, 3))
            for t, r in zip(reversal["tests"], reversal["base"].residuals):
                phase = (t.kept / t.period_samples) % 1.0
                ax.plot(phase, r / 1e3, ".", color="C1", ms=2, alpha=0.5)
            ax.set_xlabel("cycle phase")
            ax.set_ylabel("residual (kN)")
            out.append(("Residual force against cycle phase with the reversals included (the reversal "
                        f"view, where stiction is scored: {_REVERSAL}; its own base model)", _png(fig)))
            plt.close(fig)

    windows = (figs or {}).get("breakaway_windows") or []
    if windows:
        ratio = data["breakaway_check"]["misfit"]["static_ratio"]
        fig, ax = plt.subplots(figsize=(6, 3))
        for w in windows:
            # time from the end of the rest (the breakaway), force in kinetic frictions with the
            # sign of the new direction of motion: about -1 before the reversal, +1 after it
            direction = np.sign(w["sliding"][-1])
            end = int(np.nonzero(w["rest"])[0][-1])
            t_ms = (np.arange(len(w["r"])) - end) * w["dt"] * 1e3
            ax.plot(t_ms, direction * w["r"] / w["kinetic"], "-", color="C0", lw=0.5, alpha=0.3)
        for level, label in ((1.0, "kinetic"), (ratio, f"static read, {ratio:.2f}")):
            ax.axhline(level, color="C3", lw=1, ls="--")
            ax.annotate(label, (ax.get_xlim()[0], level), va="bottom", fontsize=8, color="C3")
        ax.set_xlabel("time from the end of the rest (ms)")
        ax.set_ylabel("friction / kinetic friction")
        out.append((f"Force the table holds through its reversals ({len(windows)} windows that selected stiction; "
                    "r = F - Me*a - Ke*u - Ce*|v|^alpha*sign(v), in kinetic frictions, signed by the new direction "
                    "of motion): a stiction rises above 1 before it breaks away", _png(fig)))
        plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 3))
    where = data["where"][:8]
    ax.barh([w["region"] for w in where], [100 * w["share"] for w in where], color="C2")
    ax.set_xlabel("share of the excess over the noise floor (%)")
    ax.invert_yaxis()
    out.append(("Where the base model misses", _png(fig)))
    plt.close(fig)
    return out


def write_html(path: Path, diagnosis) -> None:
    data = diagnosis.to_json()
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>bayes-sst diagnosis</title>",
             "<style>body{font-family:sans-serif;max-width:900px;margin:auto} pre{background:#f4f4f4;padding:8px}"
             "table{border-collapse:collapse} td,th{border:1px solid #ccc;padding:3px 6px}</style></head><body>",
             f"<h1>Diagnosis: {html.escape(data['series'])}</h1>",
             f"<p><b>{html.escape(data['verdict'])}</b></p>",
             "<pre>" + html.escape(format_diagnosis(data)) + "</pre>",
             "<h2>Ranking</h2><table><tr><th>effect</th><th>equation</th><th>score (nats)</th><th>se</th>"
             "<th>parameters (SI)</th></tr>"]
    for r in data["ranking"]:
        params = "; ".join(f"{k} = {v['mean']:.4g} &plusmn; {v['sd']:.2g}" for k, v in r["params"].items())
        parts.append(f"<tr><td>{html.escape(r['name'])}</td><td>{html.escape(r['equation'])}</td>"
                     f"<td>{r['score']:.1f}</td><td>{r['score_se']:.1f}</td><td>{params}</td></tr>")
    parts.append("</table>")
    for caption, png in figures(diagnosis):
        parts.append(f"<figure><img src='data:image/png;base64,{png}'><figcaption>{html.escape(caption)}"
                     "</figcaption></figure>")
    parts.append("</body></html>")
    path.write_text("\n".join(parts))


def write_diagnosis(out_dir, diagnosis, *, overwrite: bool = False) -> None:
    """Write diagnosis.json, diagnosis.txt and diagnosis.html into a new folder, atomically."""
    from bayes_sst.io import atomic_output_dir, write_json_atomic

    data = diagnosis.to_json()
    with atomic_output_dir(out_dir, overwrite=overwrite) as tmp:
        write_json_atomic(Path(tmp) / DIAGNOSIS_JSON, _plain(data))
        (Path(tmp) / DIAGNOSIS_TEXT).write_text(format_diagnosis(data) + "\n")
        write_html(Path(tmp) / DIAGNOSIS_HTML, diagnosis)


def _plain(x):
    """numpy scalars and arrays to plain json types."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, np.generic):
        return x.item()
    return x
