"""The study report: ``results.json`` and a self-contained ``report.html``.

Everything is read back from the study store, so the report can be (re)written at any time
after the stages it shows. Figures are PNGs embedded as base64 (the HTML file stands alone) and
also written to ``figures/`` next to it. All files are written atomically (temporary file in the
same folder, then ``os.replace``), so a reader never sees a half-written report.
"""

from __future__ import annotations

import base64
import html
import io
import json
import time
from pathlib import Path

import numpy as np

from flexparcel.io.atomic import write_atomic

__all__ = ["write_report", "write_atomic", "screening_section"]


def _finite(obj):
    """Replace NaN/inf by None so results.json is strict JSON."""
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


# -- formatting helpers ----------------------------------------------------------------------


def _fmt(v, digits: int = 4) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if v != v:
            return "–"
        if v == 0:
            return "0"
        if abs(v) >= 1e5 or abs(v) < 1e-3:
            return f"{v:.{digits - 1}e}"
        return f"{v:.{digits}g}"
    return html.escape(str(v))


def _loo_sentence(gp: dict, unit: str) -> str:
    """The leave-one-out comparison of a fused surrogate with the high-only GP, or ""
    where the fit has none (fewer than three high runs, or a fit stored before it)."""
    fused, high = gp.get("loo_rmse"), gp.get("high_only_loo_rmse")
    if fused is None or high is None or fused != fused or high != high:
        return ""
    return (
        f" Leaving each of the {gp['n_high']} high runs out once (trained on all low runs "
        f"and the other high runs): fused RMSE <b>{_fmt(fused)}</b> {unit}, high-only "
        f"<b>{_fmt(high)}</b> {unit}."
    )


def _range_sentence(opt: dict) -> str:
    """A warning for each target outside its response's range over the design (empty where
    every target lies inside)."""
    out = [t for t in opt["targets"] if t.get("in_design_range") is False]
    if not out:
        return ""
    parts = [
        f"{html.escape(t['experiment'])}.{html.escape(t['response'])}: target "
        f"{_fmt(t['target'])} {html.escape(t['unit'])}, design {_fmt(t['design_range'][0])} … "
        f"{_fmt(t['design_range'][1])}"
        for t in out
    ]
    return (
        f"<p><b>Targets outside the range of their design runs</b> ({'; '.join(parts)}): no "
        "run of the design reached them, so the optimum trades them against the other "
        "targets by their weights, and with weights 1/range an unreachable target may set the "
        "optimum on its own.</p>"
    )


def _reach_sentence(opt: dict) -> str:
    """Where a design had runs that did not reach their responses: the optimum's probability
    of reaching them, against the bound the optimiser kept (empty otherwise)."""
    reach = opt.get("reach") or {}
    if not reach:
        return ""
    p_min = opt["min_reach_probability"]
    parts = [
        f"{html.escape(e)} {_fmt(v['probability'], 3)} ({v['n_not_reached']} of "
        f"{v['n_reached'] + v['n_not_reached']} design runs did not reach their responses)"
        for e, v in reach.items()
    ]
    bound = (
        f"the optimiser kept it at least {_fmt(p_min, 3)} (quadratic penalty)"
        if p_min > 0
        else "unconstrained (min_reach_probability = 0)"
    )
    low = [e for e, v in reach.items() if v["probability"] < max(p_min, 0.5) - 0.05]
    warn = (
        f" <b>The optimum lies where {', '.join(map(html.escape, low))} may not reach its "
        "responses: the surrogates extrapolate there.</b>"
        if low
        else ""
    )
    return (
        "<p>Probability that a run at the optimum reaches its responses, by a Gaussian-process "
        f"classifier of the design's outcomes: {'; '.join(parts)}; {bound}.{warn}</p>"
    )


def _table(header: list[str], rows: list[list], classes: list[str] | None = None) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = []
    for i, row in enumerate(rows):
        cls = f' class="{classes[i]}"' if classes and classes[i] else ""
        body.append(f"<tr{cls}>" + "".join(f"<td>{_fmt(v)}</td>" for v in row) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


class _Figures:
    """Collects matplotlib figures as PNG bytes (embedded and written to ``figures/``)."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.files: list[Path] = []

    def add(self, fig, name: str) -> str:
        import matplotlib.pyplot as plt

        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        png = buf.getvalue()
        self.files.append(write_atomic(self.folder / f"{name}.png", png))
        b64 = base64.b64encode(png).decode("ascii")
        return f'<img alt="{html.escape(name)}" src="data:image/png;base64,{b64}">'


# -- figures ---------------------------------------------------------------------------------


def _screening_figures(figs: _Figures, exp: str, res: dict) -> str:
    import matplotlib.pyplot as plt

    out = []
    names = res["parameters"]
    for r, an in res["anova"].items():
        # constrained: the Pareto chart's interaction names need room left of its bars
        fig, axes = plt.subplots(1, 2, figsize=(12, 4), layout="constrained")
        # Response (main-effects) plot, as the paper's Fig. 31: mean response at each level.
        ax = axes[0]
        sig = set(an["significant_factors"])
        for j, n in enumerate(names):
            lo, hi = an["main_effect_means"][n]
            color = "tab:green" if n in sig else "tab:red"
            ax.plot([2 * j, 2 * j + 1], [lo, hi], "o-", color=color)
        ax.set_xticks([2 * j + 0.5 for j in range(len(names))])
        ax.set_xticklabels(names, rotation=30, ha="right", fontsize=8)
        ax.set_ylabel(f"mean {r}")
        ax.set_title("response plot (low -> high; green = significant)", fontsize=9)
        # Pareto chart of the standardised effects with the significance threshold.
        ax = axes[1]
        rows = [row for row in an["table"] if row["term"] != "Residual"]
        rows.sort(key=lambda row: -abs(row["F"]))
        rows = rows[:20]
        from scipy import stats

        if an["method"] == "anova":
            vals = [np.sqrt(row["F"]) for row in rows]
            thr = np.sqrt(stats.f.isf(an["alpha"], 1, an["residual_df"]))
            xlabel = "|t| = sqrt(F)"
        else:
            vals = [abs(row["effect"]) for row in rows]
            thr = an["margin_of_error"]
            xlabel = "|effect| (Lenth ME line)"
        colors = ["tab:green" if row["significant"] else "tab:red" for row in rows]
        y = np.arange(len(rows))[::-1]
        ax.barh(y, vals, color=colors)
        ax.set_yticks(y)
        ax.set_yticklabels([row["term"] for row in rows], fontsize=7)
        ax.axvline(thr, color="k", ls="--", lw=1)
        ax.set_xlabel(xlabel)
        ax.set_title(f"Pareto of effects, alpha = {an['alpha']}", fontsize=9)
        fig.suptitle(f"{exp}: screening of {r}", fontsize=10)
        out.append(figs.add(fig, f"screening_{exp}_{r}"))
    return "".join(out)


def screening_section(figs: _Figures, e: str, sc: dict) -> str:
    """The HTML of experiment ``e``'s screening result ``sc``: the design, the ANOVA (or Lenth)
    table per response, the response plots and Pareto charts."""
    parts: list[str] = []
    add = parts.append
    add("<h3>Screening</h3>")
    add(
        f"<p>{sc['design']} design ({len(sc['coded'])} runs"
        + (f", generators {', '.join(sc['generators'])}" if sc["generators"] else "")
        + f"). Significant parameters: <b>{', '.join(sc['significant'])}</b>; frozen: "
        + (", ".join(f"{k} = {_fmt(v)}" for k, v in sc["frozen"].items()) or "none")
        + "</p>"
    )
    hdr = [*sc["parameters"], *sc["responses"]]
    rows = [
        [*coded, *(sc["responses"][r][k] for r in sc["responses"])]
        for k, coded in enumerate(sc["coded"])
    ]
    add(
        "<details><summary>factorial design table (coded units)</summary>"
        + _table(hdr, rows)
        + "</details>"
    )
    for r, an in sc["anova"].items():
        title = "ANOVA" if an["method"] == "anova" else "Lenth effects"
        add(f"<h4>{title}: {html.escape(r)}</h4>")
        if an.get("method_reason"):
            add(f"<p class='note'>method: {html.escape(an['method_reason'])}</p>")
        trs = [
            [row["term"], row["df"], row["sum_sq"], row["mean_sq"], row["F"], row["p"]]
            + [row["effect"], None if row["term"] == "Residual" else row["significant"]]
            for row in an["table"]
        ]
        cls = [
            "" if row["term"] == "Residual" else ("sig" if row["significant"] else "ns")
            for row in an["table"]
        ]
        add(_table(["term", "df", "SS", "MS", "F", "p", "effect", "significant"], trs, cls))
        if an["method"] == "lenth":
            add(
                f"<p class='note'>PSE = {_fmt(an['pse'])}, margin of error = "
                f"{_fmt(an['margin_of_error'])}</p>"
            )
        else:
            add(
                "<p class='note'>Main effects and two-factor interactions; higher-order "
                "interactions pooled into the residual. alpha = "
                f"{an['alpha']}</p>"
            )
        if an["aliased"]:
            add(
                "<p class='note'>aliased (not estimated): "
                + ", ".join(f"{k} = {v}" for k, v in list(an["aliased"].items())[:30])
                + "</p>"
            )
    add(_screening_figures(figs, e, sc))
    if sc.get("not_analysed"):
        add(
            "<p class='note'>not analysed: "
            + "; ".join(
                f"{html.escape(k)} ({html.escape(v)})" for k, v in sc["not_analysed"].items()
            )
            + "</p>"
        )
    return "".join(parts)


def _log_axis(axis) -> None:
    """Plain numbers at 1-2-5 ticks on a log axis (no overlapping 'a x 10^b' minor labels)."""
    from matplotlib import ticker

    axis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(ticker.NullFormatter())


def _residual_figure(figs: _Figures, exp: str, r: str, gp: dict, unit: str) -> str:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    ht, hp, hs = (np.asarray(gp[k]) for k in ("holdout_true", "holdout_pred", "holdout_std"))
    ax = axes[0]
    lo = min(np.min(ht) if ht.size else np.inf, np.min(gp["cv_pred"]))
    hi = max(np.max(ht) if ht.size else -np.inf, np.max(gp["cv_pred"]))
    ax.plot([lo, hi], [lo, hi], "k-", lw=0.8)
    if gp.get("cv_true"):
        ax.plot(gp["cv_true"], gp["cv_pred"], ".", color="0.6", label="CV out-of-fold")
    ax.errorbar(ht, hp, yerr=2 * hs, fmt="o", color="tab:blue", label="hold-out (±2σ)")
    ax.set_xlabel(f"simulated {r} [{unit}]" if unit else f"simulated {r}")
    ax.set_ylabel("surrogate prediction")
    ax.legend(fontsize=8)
    ax.set_title(f"hold-out RMSE = {_fmt(gp['holdout_rmse'])}", fontsize=9)
    ax = axes[1]
    ax.axhline(0, color="k", lw=0.8)
    if gp.get("cv_true"):
        cp, ct = np.asarray(gp["cv_pred"]), np.asarray(gp["cv_true"])
        ax.plot(cp, cp - ct, ".", color="0.6", label="CV out-of-fold")
    ax.plot(hp, hp - ht, "o", color="tab:blue", label="hold-out")
    ax.legend(fontsize=8)
    ax.set_xlabel("surrogate prediction")
    ax.set_ylabel("residual (predicted - simulated)")
    ax.set_title(f"residuals, kernel {gp['kernel']}", fontsize=9)
    fig.suptitle(f"{exp}: {r}", fontsize=10)
    return figs.add(fig, f"residuals_{exp}_{r}")


def _contour_figure(figs, study, exp, r, surrogate, fit, target, optimum, reach=None) -> str:
    """The surrogate of response ``r`` over its two most influential inputs, with the target
    line and the optimum; with ``reach`` (a :class:`ReachClassifier`) and two or more inputs
    also its 0.5 line and the design runs that did not reach their responses."""
    import matplotlib.pyplot as plt

    active = fit["active"]
    space = study.config.experiment_space(exp, active)
    x_opt = np.array([optimum[p] for p in active]) if optimum else space.nominal
    ls = np.asarray(fit["responses"][r]["length_scales"])
    if len(active) == 1:
        fig, ax = plt.subplots(figsize=(5.5, 3.6))
        u = np.linspace(0, 1, 200)
        X = space.from_unit(u[:, None])
        m, s = surrogate.predict(X, return_std=True)
        ax.plot(X[:, 0], m, "b-")
        ax.fill_between(X[:, 0], m - 2 * s, m + 2 * s, alpha=0.2)
        ax.axhline(target.value, color="tab:green", lw=2, label="target")
        if optimum:
            ax.axvline(x_opt[0], color="tab:red", ls="--", label="optimum")
        ax.set_xlabel(f"{active[0]} [{space.parameters[0].unit}]")
        ax.set_ylabel(r)
        if space.parameters[0].scale == "log":
            ax.set_xscale("log")
            _log_axis(ax.xaxis)
        ax.legend(fontsize=8)
        return figs.add(fig, f"contour_{exp}_{r}")
    # The two most influential inputs (shortest length scales); the rest held at the optimum.
    i, j = sorted(np.argsort(ls)[:2])
    n = 60
    g = np.linspace(0, 1, n)
    GI, GJ = np.meshgrid(g, g)
    U = np.tile(space.to_unit(x_opt[None, :])[0], (n * n, 1))
    U[:, i], U[:, j] = GI.ravel(), GJ.ravel()
    X = space.from_unit(U)
    Z = surrogate.predict(X).reshape(n, n)
    XI, XJ = X[:, i].reshape(n, n), X[:, j].reshape(n, n)
    fig, ax = plt.subplots(figsize=(5.8, 4.4))
    cs = ax.contourf(XI, XJ, Z, levels=20, cmap="viridis")
    ax.contour(XI, XJ, Z, levels=10, colors="k", linewidths=0.4)
    fig.colorbar(cs, ax=ax, label=f"{r} [{target.unit}]" if target.unit else r)
    if Z.min() <= target.value <= Z.max():
        ax.contour(XI, XJ, Z, levels=[target.value], colors="tab:green", linewidths=2.5)
    ax.plot([], [], color="tab:green", lw=2.5, label=f"target {_fmt(target.value)}")
    if reach is not None:
        _draw_reach(ax, study, exp, fit, reach, X, (XI, XJ), (i, j))
    if optimum:
        ax.plot(x_opt[i], x_opt[j], marker="*", color="tab:red", ms=16, mec="w", label="optimum")
    p_i, p_j = space.parameters[i], space.parameters[j]
    ax.set_xlabel(f"{p_i.name} [{p_i.unit}]")
    ax.set_ylabel(f"{p_j.name} [{p_j.unit}]")
    if p_i.scale == "log":
        ax.set_xscale("log")
        _log_axis(ax.xaxis)
    if p_j.scale == "log":
        ax.set_yscale("log")
        _log_axis(ax.yaxis)
    others = [p for k, p in enumerate(active) if k not in (i, j)]
    title = f"{exp}: surrogate of {r}"
    if others:
        title += "\n(" + ", ".join(f"{p} = {_fmt(optimum[p] if optimum else 0)}" for p in others)
        title += " at the optimum)"
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8, loc="best")
    return figs.add(fig, f"contour_{exp}_{r}")


def _draw_reach(ax, study, exp, fit, reach, X, grid, axes) -> None:
    """The classifier's 0.5 line (dashed) and the runs not reached (x) on a contour plot."""
    XI, XJ = grid
    i, j = axes
    P = reach.probability(X).reshape(XI.shape)
    if P.min() < 0.5 < P.max():
        ax.contour(XI, XJ, P, levels=[0.5], colors="w", linewidths=1.8, linestyles="--")
        ax.plot([], [], color="w", ls="--", lw=1.8, label="reach probability 0.5")
    outcomes = zip(fit["reach"]["run_keys"], fit["reach"]["reached"], strict=True)
    rows = study.store.get_runs([k for k, ok in outcomes if not ok])
    sub = study.config.experiment_space(exp, fit["active"])
    Xn = sub.from_dicts(r["params"] for r in rows)
    ax.plot(Xn[:, i], Xn[:, j], "x", color="tab:red", ms=7, mew=2, label="not reached")


# -- report ----------------------------------------------------------------------------------

_CSS = """
body{font-family:system-ui,sans-serif;margin:2em;max-width:1200px;color:#222}
table{border-collapse:collapse;margin:.5em 0 1em;font-size:13px}
th,td{border:1px solid #ccc;padding:3px 7px;text-align:right}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}
tr.sig td{background:#e3f6e3}tr.ns td{background:#fbe9e9}tr.best td{font-weight:bold}
img{max-width:100%;margin:.3em 0}h2{border-bottom:2px solid #ddd;margin-top:1.6em}
.note{color:#555;font-size:13px}details{margin:.5em 0}pre{white-space:pre-wrap;font-size:12px}
"""


def write_report(study) -> Path:
    """Write ``results.json``, ``figures/*.png`` and ``report.html`` of ``study`` (a
    :class:`flexparcel.calibration.study.Study`, which calls this; not imported here, so that
    the two modules form no cycle); returns the HTML path."""
    import matplotlib

    matplotlib.use("Agg", force=False)

    from flexparcel._version import __version__

    c = study.config
    store = study.store
    out = Path(study.output)
    figs = _Figures(out / "figures")
    parts: list[str] = []
    add = parts.append

    screening = {e: store.get_result("screening", e) for e in c.experiments}
    design = {e: store.get_result("design", e) for e in c.experiments}
    fits = {e: store.get_result("fit", e) for e in c.experiments}
    opt = store.get_result("optimise", "")
    val = store.get_result("validation", "")
    counts = store.status_counts()
    optimum = opt["optimum"] if opt else None

    add(f"<h1>Calibration study: {html.escape(c.name)}</h1>")
    if c.description:
        add(f"<p>{html.escape(c.description)}</p>")
    add(
        f"<p class='note'>study file {html.escape(str(c.path))}; store "
        f"{html.escape(str(study.store_path))}; flexparcel {__version__}; written "
        f"{time.strftime('%Y-%m-%d %H:%M:%S')}. Runs in store: "
        + ", ".join(f"{k} {v}" for k, v in counts.items())
        + "</p>"
    )

    # parameters
    add("<h2>Parameters</h2>")
    calibrated = set(opt["calibrated"]) if opt else set()
    prow = []
    for p in c.parameters.parameters:
        role = "calibrated" if p.name in calibrated else ("frozen" if opt else "")
        prow.append([p.name, p.unit, p.lower, p.upper, p.scale, p.nominal_value, role])
    add(_table(["parameter", "unit", "lower", "upper", "scale", "nominal", "role"], prow))

    for exp in c.experiments.values():
        e = exp.name
        add(f"<h2>Experiment {html.escape(e)}</h2>")
        add(
            f"<p class='note'>simulator <b>{html.escape(exp.simulator)}</b>, setup "
            f"<code>{html.escape(json.dumps(dict(exp.setup)))}</code>; parameters "
            f"{', '.join(exp.parameters)}</p>"
        )
        if screening[e]:
            add(screening_section(figs, e, screening[e]))

        d, fit = design[e], fits[e]
        if d:
            add("<h3>Design (Latin hypercube)</h3>")
            keys = store.design_keys("design", e)[: d["runs"]]
            runs = store.get_runs(keys)
            add(
                f"<p>{len(runs)} runs over {', '.join(d['active'])}; frozen: "
                + (", ".join(f"{k} = {_fmt(v)}" for k, v in d["frozen"].items()) or "none")
                + f"; done {sum(r['status'] == 'done' for r in runs)}, failed "
                + f"{sum(r['status'] == 'failed' for r in runs)}.</p>"
            )
            rs = list(exp.responses)
            rows = [
                [i, *(r["params"][p] for p in d["active"])]
                + [(r["responses"] or {}).get(x) for x in rs]
                + [r["status"], r["attempts"], r["wall_s"]]
                for i, r in enumerate(runs)
            ]
            add(
                "<details><summary>design table</summary>"
                + _table(["#", *d["active"], *rs, "status", "attempts", "wall [s]"], rows)
                + "</details>"
            )
        if fit:
            add("<h3>Surrogates (Gaussian process regression)</h3>")
            surrogates = study._surrogates(exp, fit)
            reach = study.reach_classifiers({e: fit}).get(e)
            for t in exp.targets:
                r = t.response
                gp = fit["responses"][r]
                add(f"<h4>{html.escape(r)}</h4>")
                krows = [[k, v, *gp["cv_rmse_folds"][k]] for k, v in sorted(gp["cv_rmse"].items())]
                kcls = ["best" if k == gp["kernel"] else "" for k, *_ in krows]
                folds = [f"fold {i + 1}" for i in range(len(krows[0]) - 2)]
                add(_table(["kernel", "mean CV RMSE", *folds], krows, kcls))
                tf = gp.get("transform", {"kind": "none"})
                if tf["kind"] == "log":
                    add(
                        f"<p class='note'>modelled as log({html.escape(r)} + "
                        f"{_fmt(tf['offset'])}); all RMSEs and predictions here are "
                        f"back-transformed to {html.escape(t.unit) or 'the response units'}.</p>"
                    )
                if "high_only_holdout_rmse" in gp:
                    unit = html.escape(t.unit)
                    add(
                        f"<p>multi-fidelity (co-kriging, y_high = rho y_low + delta; Kennedy & "
                        f"O'Hagan 2000): rho = <b>{_fmt(gp['rho'])}</b>, discrepancy kernel "
                        f"<code>{html.escape(gp['delta_kernel_repr'])}</code>. Low level: kernel "
                        f"<b>{gp['kernel']}</b> by CV (table above), hold-out RMSE "
                        f"{_fmt(gp['low_holdout_rmse'])} {unit} on its own runs. On "
                        f"{len(gp['high_holdout_index'])} held-out high-fidelity runs (of "
                        f"{gp['n_high']}): fused surrogate RMSE <b>"
                        f"{_fmt(gp['holdout_rmse'])}</b> {unit}, high-only GP trained on the "
                        f"same high runs <b>{_fmt(gp['high_only_holdout_rmse'])}</b> {unit} "
                        f"(high-level range {_fmt(fit['range'][r][0])} … "
                        f"{_fmt(fit['range'][r][1])}).{_loo_sentence(gp, unit)}</p>"
                    )
                else:
                    add(
                        f"<p>chosen kernel <b>{gp['kernel']}</b>: <code>"
                        f"{html.escape(gp['kernel_repr'])}</code>; hold-out RMSE "
                        f"<b>{_fmt(gp['holdout_rmse'])}</b> {html.escape(t.unit)} on "
                        f"{len(gp['holdout_index'])} untouched runs (response range "
                        f"{_fmt(fit['range'][r][0])} … {_fmt(fit['range'][r][1])}).</p>"
                    )
                add(_residual_figure(figs, e, r, gp, t.unit))
                add(_contour_figure(figs, study, e, r, surrogates[r], fit, t, optimum, reach))

    if opt:
        add("<h2>Calibration</h2>")
        add(
            "<p>Minimised <code>error = sum_i (w_i (Z_target,i - Z_pred,i))^2</code> with "
            f"bounded Nelder–Mead from {len(opt['starts'])} starts; error at the optimum "
            f"<b>{_fmt(opt['error'])}</b>.</p>"
        )
        rows = []
        for n in opt["calibrated"]:
            p = c.parameters[n]
            rows.append([n, opt["optimum"][n], p.unit, p.lower, p.upper, opt["optimum_unit"][n]])
        add(_table(["parameter", "optimum", "unit", "lower", "upper", "unit coordinate"], rows))
        rows = [
            [
                f"{t['experiment']}.{t['response']}",
                t["target"],
                t["predicted"],
                t["std"],
                t["weight"],
                t["weight_source"],
            ]
            for t in opt["targets"]
        ]
        add(_table(["response", "target", "predicted", "GP std", "weight", "weight from"], rows))
        add(_range_sentence(opt))
        add(_reach_sentence(opt))
        srows = [
            [i + 1, s["error"], s.get("penalty", 0.0), s["nit"], s["success"], *s["x"]]
            for i, s in enumerate(opt["starts"])
        ]
        head = ["start", "error", "reach penalty", "iterations", "converged"]
        add(
            "<details><summary>Nelder–Mead starts</summary>"
            + _table([*head, *opt["calibrated"]], srows)
            + "</details>"
        )
    if val:
        add("<h2>Validation at the optimum</h2>")
        rows = [
            [
                f"{v['experiment']}.{v['response']}",
                v["target"],
                v["predicted"],
                v["simulated"],
                None if v["simulated"] is None else v["simulated"] - v["target"],
                v["within_spread"],
                v["status"],
                v["wall_s"],
            ]
            for v in val["rows"]
        ]
        add(
            _table(
                [
                    "response",
                    "target",
                    "surrogate",
                    "simulated",
                    "simulated - target",
                    "within spread",
                    "status",
                    "wall [s]",
                ],
                rows,
            )
        )
    failed = [r for r in store.all_runs() if r["status"] == "failed"]
    if failed:
        add("<h2>Failed runs</h2>")
        for r in failed[:50]:
            add(
                f"<details><summary>{r['run_key'][:12]} ({r['attempts']} attempts)</summary>"
                f"<pre>{html.escape(r['error'] or '')}</pre></details>"
            )

    page = (
        "<!DOCTYPE html><html><head><meta charset='utf-8'>"
        f"<title>{html.escape(c.name)} – flexparcel calibration</title>"
        f"<style>{_CSS}</style></head><body>{''.join(parts)}</body></html>"
    )
    results = {
        "study": c.name,
        "flexparcel_version": __version__,
        "run_counts": counts,
        "screening": {e: v for e, v in screening.items() if v},
        "design": {e: v for e, v in design.items() if v},
        "fit": {
            e: {
                "active": v["active"],
                "n_runs": len(v["run_keys"]),
                "n_failed": v["n_failed"],
                "range": v["range"],
                "responses": {
                    r: {
                        k: g[k]
                        for k in (
                            "kernel",
                            "kernel_repr",
                            "cv_rmse",
                            "holdout_rmse",
                            "theta",
                            "transform",
                            "rho",
                            "high_only_holdout_rmse",
                            "loo_rmse",
                            "high_only_loo_rmse",
                            "low_holdout_rmse",
                        )
                        if k in g
                    }
                    for r, g in v["responses"].items()
                },
            }
            for e, v in fits.items()
            if v
        },
        "optimise": opt,
        "validation": val,
        "figures": [str(p.relative_to(out)) for p in figs.files],
    }
    write_atomic(out / "results.json", json.dumps(_finite(results), indent=2, allow_nan=False))
    return write_atomic(out / "report.html", page)
