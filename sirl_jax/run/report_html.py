"""The HTML of `report`: a `report_data.Report` as one page, styles inline, media as data URIs.

No script, no external reference (fonts, styles, images and video all inside the file), so it
opens offline in any browser and prints as it shows.
"""

from __future__ import annotations

import html
import math

from sirl_jax.run.report_data import POLICIES, VIDEO_LIMIT, Report, data_uri

_CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;color:#1d2330;
background:#f4f5f7;margin:0}
main{max-width:1180px;margin:0 auto;padding:20px 28px 40px}
h1{font-size:22px;margin:8px 0 2px}h2{font-size:16px;margin:26px 0 8px;border-bottom:1px solid
#d5d9e0;padding-bottom:4px}
.sub{color:#5b6475;margin:0 0 12px}
.cards{display:flex;flex-wrap:wrap;gap:10px}
.card{background:#fff;border:1px solid #dde1e8;border-radius:6px;padding:8px 14px;min-width:140px}
.card b{display:block;font-size:20px}.card span{color:#5b6475;font-size:12px}
table{border-collapse:collapse;background:#fff;font-variant-numeric:tabular-nums}
th,td{border:1px solid #dde1e8;padding:3px 10px;text-align:right}
th{background:#eef0f4;font-weight:600}td.l,th.l{text-align:left}
.ok{color:#17703a;font-weight:600}.bad{color:#b3261e;font-weight:600}
img,video{max-width:100%;background:#fff;border:1px solid #dde1e8;border-radius:4px}
.note{color:#7a4b00;background:#fff6e0;border-left:3px solid #e0a000;padding:3px 8px;margin:4px 0}
code{background:#eef0f4;padding:0 3px;border-radius:3px}
details{background:#fff;border:1px solid #dde1e8;border-radius:6px;padding:6px 12px}
.cfg{column-width:300px;column-gap:24px;font-size:12px;margin-top:6px}
.cfg div{break-inside:avoid;padding:1px 0;border-bottom:1px dotted #e3e6eb}
"""


def _e(value) -> str:
    return html.escape(str(value))


def _num(value: float | None, fmt: str = ",.1f") -> str:
    if value is None or not math.isfinite(value):
        return "–"
    return format(value, fmt)


def _card(value: str, label: str, cls: str = "") -> str:
    return f'<div class="card"><b class="{cls}">{_e(value)}</b><span>{_e(label)}</span></div>'


def _summary(r: Report) -> str:
    cards = [_card(f"{r.env_steps:,}", "env steps logged"),
             _card(f"{len(r.checkpoints)}", f"checkpoint(s), last {r.checkpoints[-1]:,}")]
    if r.eval_rows:
        last = r.eval_rows[-1]
        for prefix, name in POLICIES:
            if f"eval/{prefix}_return" in last:
                cards.append(_card(_num(last[f"eval/{prefix}_return"]),
                                   f"{name} eval return @ {int(last['env_steps']):,}"))
                success = last.get(f"eval/{prefix}_success", math.nan)
                cls = "ok" if success >= 0.5 else "bad"
                cards.append(_card(_num(success, ".2f"), f"{name} success rate", cls))
    if r.best is not None:
        cards.append(_card(f"{r.best['step']:,}", f"best checkpoint ({r.best['metric']} "
                           f"{_num(r.best['value'])}; --best)"))  # fmt: skip
    cards.append(_card(_num(r.r_max_last), f"R_max (last; best {_num(r.r_max_best)})"))
    blowups = sum(v for k, v in r.counters.items() if "blow-up" in k)
    cards.append(_card(f"{blowups:g}", "blow-ups (train + eval)", "bad" if blowups else "ok"))
    return f'<div class="cards">{"".join(cards)}</div>'


def _eval_table(r: Report) -> str:
    if not r.eval_rows:
        return ""
    present = [(p, n) for p, n in POLICIES if any(f"eval/{p}_return" in x for x in r.eval_rows)]
    head = '<tr><th rowspan="2">env step</th><th rowspan="2">episodes</th>' + "".join(
        f'<th colspan="3">{_e(n)}</th>' for _, n in present) + "</tr><tr>" + (
        "<th>return ± std</th><th>length</th><th>success</th>" * len(present)) + "</tr>"
    body = []
    for row in r.eval_rows:
        cells = [f"{int(row['env_steps']):,}", _num(row.get("episodes"), ".0f")]
        for p, _ in present:
            ret, std = row.get(f"eval/{p}_return"), row.get(f"eval/{p}_return_std")
            cells += [f"{_num(ret)} ± {_num(std)}", _num(row.get(f"eval/{p}_length"), ".0f"),
                      _num(row.get(f"eval/{p}_success"), ".2f")]  # fmt: skip
        body.append("<tr>" + "".join(f"<td>{_e(c)}</td>" for c in cells) + "</tr>")
    random = ("" if r.random_return is None else
              f"<p>Uniform random policy (from <code>eval</code>): return "
              f"{_num(r.random_return)}.</p>")  # fmt: skip
    return (f"<p class=sub>From {_e(r.eval_source)}; success is the fraction of episodes over "
            f"the task's success bar.</p><table>{head}{''.join(body)}</table>{random}")


def _counters(r: Report) -> str:
    rows = "".join(f'<tr><td class="l">{_e(k)}</td><td class="{"bad" if v else "ok"}">'
                   f"{_e(format(v, 'g'))}</td></tr>" for k, v in r.counters.items())  # fmt: skip
    return f'<table><tr><th class="l">counter</th><th>total</th></tr>{rows}</table>'


def _video(r: Report) -> str:
    if r.video is None:
        return (f"<p class=sub>No video in the run directory; write one with <code>python -m "
                f"sirl_jax render {_e(r.run_dir)}</code>.</p>")  # fmt: skip
    size = r.video.stat().st_size
    name = _e(r.video.relative_to(r.run_dir))
    if size > VIDEO_LIMIT:
        return f"<p class=note>{name} ({size / 2**20:.0f} MiB) is too large to embed.</p>"
    uri = data_uri("video/mp4", r.video.read_bytes())
    return (f'<p class=sub>{name}</p><video controls loop muted playsinline preload="auto" '
            f'src="{uri}"></video>')  # fmt: skip


def _training_videos(r: Report) -> str:
    """Every training video in env-step order, embedded while they fit `VIDEO_LIMIT` together."""
    if not r.videos:
        return ""
    items, left = [], VIDEO_LIMIT
    for path in r.videos:
        name, size = _e(path.relative_to(r.run_dir)), path.stat().st_size
        step = int(path.stem.removeprefix("step_"))
        if size <= left:
            left -= size
            uri = data_uri("video/mp4", path.read_bytes())
            items.append(f'<figure><figcaption class=sub>env step {step:,}: {name}</figcaption>'
                         f'<video controls loop muted playsinline src="{uri}"></video></figure>')
        else:
            items.append(f"<p class=note>env step {step:,}: {name} ({size / 2**20:.1f} MiB, "
                         "not embedded: the page holds the earlier ones)</p>")  # fmt: skip
    return f"<h2>Training videos ({len(r.videos)})</h2>" + "".join(items)


def _config(r: Report) -> str:
    fields = "".join(f"<div><code>{_e(k)}</code> {_e(v)}</div>"
                     for k, v in sorted(r.config.items()))  # fmt: skip
    starts = "".join(
        f'<tr><td class="l">{_e(s.get("started", "?"))}</td><td class="l">'
        f'{_e(s.get("git_commit") or "?")}</td><td class="l">{_e(s.get("backend", "?"))}: '
        f'{_e(", ".join(s.get("devices", [])))}</td><td class="l">jax {_e(s.get("jax", "?"))},'
        f' mujoco {_e(s.get("mujoco", "?"))}</td></tr>' for s in r.starts)  # fmt: skip
    return (f"<details open><summary>config.json ({len(r.config)} fields)</summary>"
            f'<div class="cfg">{fields}</div></details><h2>Starts (versions.json)</h2><table>'
            '<tr><th class="l">started (UTC)</th><th class="l">git commit</th><th class="l">'
            f'device</th><th class="l">versions</th></tr>{starts}</table>')  # fmt: skip


def to_html(r: Report) -> str:
    """The page of a report, as one string."""
    curves = ("" if r.plot_png is None else
              f'<img alt="curves" src="{data_uri("image/png", r.plot_png)}">')  # fmt: skip
    notes = "".join(f"<div class=note>{_e(n)}</div>" for n in r.notes)
    title = f"{r.task} seed {r.seed}: {r.run_dir.name}"
    return page(title, f"""<h1>{_e(r.task)} · seed {r.seed}</h1>
<p class=sub>{_e(r.task_line)} · run {_e(r.run_dir.name)} · sirl_jax run report</p>
{_summary(r)}
<h2>Cost</h2><p>{_e(r.cost)}</p>
<h2>Evaluation over checkpoints</h2>{_eval_table(r) or "<p class=sub>none yet</p>"}
<h2>Curves</h2>{curves}{notes}
<h2>Counters</h2>{_counters(r)}
<h2>Latest video</h2>{_video(r)}{_training_videos(r)}
<h2>Config</h2>{_config(r)}
""")


def page(title: str, body: str) -> str:
    """A whole page: `body` in the report's inline styles, no external reference."""
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{_e(title)}</title>
<meta name="viewport" content="width=device-width, initial-scale=1"><style>{_CSS}</style></head>
<body><main>
{body}</main></body></html>
"""


__all__ = ["page", "to_html"]
