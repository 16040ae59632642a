"""`mcz classify`: PPCA class recognition (thesis section 3.2.4, tables 4.5 to 4.8).

    mcz classify --train LABELS.csv TRAIN... --test TEST... [-r normalised] [--threshold auto|T] [--json]

Each class named in LABELS.csv is modelled by probabilistic PCA over the poses of its
training clips (Q components holding 99 % of the variance, rho the mean of the other
eigenvalues). Every pose of every test clip gets a log density under every class; the
command prints, per test clip, the share of its poses above the threshold for each
class, then (for test clips LABELS.csv also names) the table in the thesis layout.
"""

from __future__ import annotations

import json

import click

from mocapzip.cli import importing
from mocapzip.cli.choices import REPRESENTATIONS
from mocapzip.cli.errors import reports_errors



class _ListOptions(click.Command):
    """`--test A B C` (and `--train LABELS A B`) as the issue writes them: every word after
    `--test` up to the next option is a test input. Click options take one value, so the
    words are rewritten to `--test A --test B --test C` before parsing."""

    def parse_args(self, ctx, args):
        out, in_test = [], False
        for word in args:
            if word == "--test":
                in_test = True
                continue
            if word.startswith("-") and word != "-":
                in_test = False
            elif in_test:
                out.extend(["--test", word])
                continue
            out.append(word)
        return super().parse_args(ctx, out)


def load_poses(inputs, representation: str, asf=None) -> tuple[list, dict[str, "object"]]:
    """The clips under `inputs` in `representation`, and their classification poses by stored path."""
    from mocapzip.inputs.clip import load_clips
    from mocapzip.inputs.discover import find_clips, no_clips
    from mocapzip.classes.ppca import classification_poses

    sources = find_clips(list(inputs), asf=asf)
    if not sources:
        raise no_clips(inputs)
    clips = load_clips(sources, representation)
    return sources, {c.source.relpath: classification_poses(c) for c in clips}


def run_classification(labels: str, train_inputs, test_inputs, representation: str = "normalised",
                       threshold="auto", variance: float = 0.99, only=None, asf=None, segment: bool = False) -> dict:
    """The whole experiment (what the command prints): train on labelled clips, score test clips.

    `segment` cuts each test clip at PPCA change points (`mocapzip.classes.segment`) and scores each
    piece on its own, as `CLIP[first:end]` (frames, end excluded): one take, several classes.
    """
    from mocapzip.classes.by_name import class_in_table, read_class_table
    from mocapzip.formats.errors import MocapFormatError
    from mocapzip.classes.ppca import classify, train_models

    table = read_class_table(labels)
    train_sources, train_poses = load_poses(train_inputs, representation, asf)
    test_sources, test_poses = load_poses(test_inputs, representation, asf)
    train = {}
    for s in train_sources:
        name = class_in_table(s, table)
        if name is None:
            raise MocapFormatError(f"training clip '{s.relpath}' has no class in the table", labels)
        if only is None or name in only:
            train[s.relpath] = name
    if not train:
        raise MocapFormatError("no training clip left (check --only)", labels)
    truth = {s.relpath: class_in_table(s, table) for s in test_sources}
    truth = {k: v for k, v in truth.items() if v is not None}
    tests = {k: v for k, v in test_poses.items() if only is None or truth.get(k) in only}
    if segment:
        from mocapzip.classes.segment import segment_take

        pieces = {}
        for key, poses in tests.items():
            cuts = segment_take(poses)
            for a, b in zip(cuts[:-1], cuts[1:]):
                name = key if len(cuts) == 2 else f"{key}[{a}:{b}]"
                pieces[name] = poses[a:b]
                if key in truth:
                    truth[name] = truth[key]
        tests = pieces
    if not tests:
        raise MocapFormatError("no test clip left (check --only)", ", ".join(map(str, test_inputs)))
    widths = {p.shape[1] for p in list(test_poses.values()) + [train_poses[k] for k in train]}
    if len(widths) > 1:
        raise MocapFormatError(f"clips have different pose widths {sorted(widths)} in {representation}: "
                               "train and test on one skeleton layout", labels)
    models = train_models(train, train_poses, variance)
    report = classify(models, tests, truth, threshold)
    report.update(representation=representation, variance_share=variance,
                  train={"clips": len(train), "frames": int(sum(train_poses[k].shape[0] for k in train))})
    return report


def _threshold(text: str):
    if text == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise click.BadParameter("expected 'auto' or a number (a log density)", param_hint="--threshold") from None


@click.command(cls=_ListOptions)
@click.option("--train", "labels", required=True, type=click.Path(dir_okay=False), metavar="LABELS.csv",
              help="Classes of the training clips: CSV/TSV rows 'clip path, class' (MANIFEST.tsv works). "
                   "The words after it are the training inputs.")
@click.argument("train_inputs", nargs=-1, required=True, type=click.Path(), metavar="TRAIN...")
@click.option("--test", "test_inputs", multiple=True, required=True, type=click.Path(), metavar="TEST...",
              help="Test clips or folders (every word up to the next option). Those LABELS.csv names "
                   "make up the confusion table.")
@click.option("-r", "--representation", type=click.Choice(REPRESENTATIONS), default="normalised", show_default=True,
              help="Pose representation; the thesis found normalised positions best. channels drops the root's channels.")
@click.option("--threshold", default="auto", show_default=True, metavar="auto|T",
              help="Log-density threshold. auto (thesis): test poses lie above it for one class on average, "
                   "i.e. the table sums to (columns x 100) %.")
@click.option("--variance", type=click.FloatRange(0, 1, min_open=True), default=0.99, show_default=True,
              help="Share of each class's variance its Q components hold.")
@click.option("--only", default=None, metavar="A,B,...", help="Keep only these classes (training and test clips).")
@click.option("--segment", is_flag=True,
              help="Cut each test clip at PPCA change points (Barbic et al.) and classify the pieces, CLIP[first:end].")
@click.option("--asf", type=click.Path(dir_okay=False), help="Skeleton for every AMC (default: the .asf in each AMC's folder; of several different ones, the one whose name begins the AMC's).")
@click.option("--json", "as_json", is_flag=True, help="Print the whole report as JSON.")
@reports_errors
def classify(labels, train_inputs, test_inputs, representation, threshold, variance, only, segment, asf, as_json):
    """Recognise motion classes with probabilistic PCA (thesis 3.2.4).

    \b
    Example (train walk/run on subject 35 and boxing on 13, test on others):
      mcz classify --train ../shared/data/MANIFEST.tsv ../shared/data/cmu/35 ../shared/data/cmu/13/13_17.amc \\
                   --test ../shared/data/cmu/07 ../shared/data/cmu/09 ../shared/data/cmu/14 --only walk,run,boxing
    """
    with importing():
        from mocapzip import progress
        from mocapzip.classes.ppca import format_table

    if as_json:  # the JSON alone on the terminal
        progress.set_quiet(True)
    chosen = None if only is None else {c.strip() for c in only.split(",") if c.strip()}
    report = run_classification(labels, train_inputs, test_inputs, representation, _threshold(threshold),
                                variance, chosen, asf, segment)
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    names = list(report["classes"])
    click.echo(f"{representation}, threshold {report['threshold']:.1f} ({report['threshold_rule'].split(':')[0]}); "
               + ", ".join(f"{n}: Q={c['components']}, rho={c['rho']:.3g}" for n, c in report["classes"].items()))
    width = max([len(c["path"]) for c in report["clips"]] + [4])
    click.echo(f"{'clip':<{width}}  {'class':>10}  " + "  ".join(f"{n:>10}" for n in names) + "  best")
    for c in report["clips"]:
        click.echo(f"{c['path']:<{width}}  {c['class'] or '-':>10}  "
                   + "  ".join(f"{c['share'][n]:>9.2f}%" for n in names) + f"  {c['best']}")
    if "table" in report:
        click.echo("")
        click.echo(format_table(report, "% of test poses above the threshold (columns: test clips by class)"))
        click.echo(f"best class (most pose votes): {report['pose_accuracy']:.1f} % of poses, "
                   f"{report['clip_accuracy']:.1f} % of clips correct")
