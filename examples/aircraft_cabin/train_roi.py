"""The paper's ROI classifier (section 4.6.1) trained on generated cabin data, with the balance
ablation: does the data train a model, and does balanced generation matter?

EfficientNet-B0 decides for each place-region crop its label as ``usdscene export rois`` gives
it by the setup's ``roi_rules`` and ``roi_ignore``: ``correct``, ``incorrect`` and ``empty`` for
the cabin's rules (a seat holding only a passenger is ``empty``). Three training sets of
equal size, each from one generator strategy over the same camera setup:

* ``balanced``: ``usdscene generate balanced`` (equal instance-frames per class, every fitting
  class × relation × place at least once);
* ``random``: ``usdscene generate random``, the naive ablation (uniformly random classes at
  uniformly random places, no balancing);
* ``single-class``: ``usdscene generate single-class`` (one class and relation per frame, at
  every place where it fits);

and one test document held apart from all three: another seed, the ``appearance`` strategy
(random appearance variants and colours), another passenger occupancy and another lighting
(dimmer, cooler ceiling lights, a low sun), rendered on its own (no frame is shared). Every
training runs for ``--seeds`` seeds; the report gives accuracy, mean per-class recall,
per-class recall, the confusion matrix, training curves and the wall time per step.

The paper's protocol: EfficientNet-B0, RMSprop, batch 40, 50 epochs. No pretrained weights can
be downloaded, so training starts from random initialisation; ``--weights FILE`` loads
ImageNet weights a user has (torchvision's ``efficientnet_b0`` state dict: the model below keeps
its parameter names; the classifier layer is left at random). ``--real-test DIR`` (one folder
per label, e.g. ``DIR/correct/*.png``) adds an evaluation on real crops.

Scaling (the defaults fit about 3 hours on a shared 2-core CPU): the paper's 224 px input costs
about 50 times the arithmetic of 32 px, and one optimiser step of EfficientNet-B0 at batch 40
took 1.5-3.7 s even at 32 px on this machine (docs/training.md). The defaults therefore keep
the protocol (model, optimiser, batch, 50 epochs, 3 seeds × 3 sets) and scale everything else:
32 px input, 400 crops per training set and 400 test crops, drawn from 6 frames × 4 seat-area
cameras (rows 03-06) at 320x240 with 4 samples per set. Measured pace: rendering the four sets
about 25 minutes; 9 trainings × 50 epochs × 10 steps at about 1.5 s, plus the test set after
every epoch, about 2.5 hours. Raise ``--size``, ``--rois-per-set``, ``--frames``, ``--width``
on a bigger machine; ``--epochs 8 --rois-per-set 240`` is the quick look of docs/training.md.

Usage::

    pip install -e '.[train]'
    python examples/aircraft_cabin/train_roi.py --work runs/roi        # render, train, report
    python examples/aircraft_cabin/train_roi.py --work runs/roi --real-test my_crops/

Everything goes under ``--work``: the documents, the rendered outputs (a re-run resumes and
reuses them), ``results.json``, ``results.md`` and ``curves.png``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

PROG = "train_roi.py"
INSTALL_HINT = "pip install 'usdscene[train]' (in a checkout: pip install -e '.[train]')"
TRAIN_SETS = ("balanced", "random", "single-class")
TEST_SET = "test"
EMPTY_LABEL = "empty"  # usdscene.converters.exports.rois.EMPTY_LABEL, without importing the library early
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")
# ImageNet statistics: what torchvision's EfficientNet-B0 weights expect.
MEAN_RGB = np.array([0.485, 0.456, 0.406], dtype=np.float32)
STD_RGB = np.array([0.229, 0.224, 0.225], dtype=np.float32)
# EfficientNet-B0 (Tan & Le, 2019, table 1): (expansion, kernel, stride, in, out, layers) per stage.
B0_STAGES = ((1, 3, 1, 32, 16, 1), (6, 3, 2, 16, 24, 2), (6, 5, 2, 24, 40, 2), (6, 3, 2, 40, 80, 3),
             (6, 5, 1, 80, 112, 3), (6, 5, 2, 112, 192, 4), (6, 3, 1, 192, 320, 1))
B0_HEAD_CHANNELS = 1280
B0_DROPOUT = 0.2
B0_STOCHASTIC_DEPTH = 0.2
CURVE_COLOURS_BGR = ((200, 90, 30), (40, 140, 230), (60, 170, 60), (160, 60, 180), (40, 40, 200))


class UsageError(Exception):
    """Bad input: printed as one line, exit 1."""


@dataclasses.dataclass(frozen=True)
class RoiSet:
    """Labelled crops.

    Attributes:
        name: set name (``balanced``, ``test``, ...).
        paths: crop image files.
        labels: label per crop (same length as ``paths``).
    """

    name: str
    paths: tuple[Path, ...]
    labels: tuple[str, ...]

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for label in self.labels:
            out[label] = out.get(label, 0) + 1
        return dict(sorted(out.items()))


# --------------------------------------------------------------------------------------------
# Optional dependency


def require_torch():
    """torch, or :class:`UsageError` naming the install command of the ``train`` extra."""
    try:
        import torch
    except ImportError:
        raise UsageError(f"training needs PyTorch, which is not installed; install the train extra: "
                         f"{INSTALL_HINT}") from None
    return torch


# --------------------------------------------------------------------------------------------
# Datasets: generate, render, read the ROI index


def cabin_setup(cameras, place_patterns, width_px: int, samples: int, *, test_lighting: bool = False):
    """The cabin setup of the campaign (``make_documents.cabin_scene``) reduced to ``cameras``,
    naming every place that matches ``place_patterns`` (so that every document crops the same
    regions); ``test_lighting`` dims and cools the ceiling lights and lowers the sun."""
    import fnmatch

    from make_documents import cabin_scene
    from usdscene import load_catalog
    from usdscene.document.model import PlaceRef

    scene = cabin_scene(frames=1, width_px=width_px, samples=samples, seed=7)
    known = [c.name for c in scene.cameras]
    unknown = [c for c in cameras if c not in known]
    if unknown:
        raise UsageError(f"--cameras: unknown camera(s) {', '.join(unknown)} (known: {', '.join(known)})")
    places = sorted(name for name in load_catalog().places("aircraft_cabin")
                    if any(fnmatch.fnmatchcase(name, p) for p in place_patterns))
    if not places:
        raise UsageError(f"--places: no cabin place matches {' '.join(place_patterns)}")
    lights = scene.lights
    if test_lighting:
        lights = tuple(dataclasses.replace(light, power_w=light.power_w * (0.35 if light.kind.value == "point" else 2.0),
                                           color_rgb=(0.8, 0.9, 1.0) if light.kind.value == "point" else (1.0, 0.75, 0.5))
                       for light in lights)
    return dataclasses.replace(
        scene, name="aircraft_cabin_roi_setup", objects=(), relations=(),
        places=tuple(PlaceRef(uid=f"place_{name}", name=name) for name in places),
        cameras=tuple(c for c in scene.cameras if c.name in cameras), lights=lights,
        description="Cabin ROI experiment setup: seat-area cameras, no luggage.")


def generate_set(work: Path, name: str, setup, options) -> Path:
    """Write the setup and generate the set's document (kept when it exists)."""
    from usdscene import generate_document, write_document, write_openlabel

    document = work / f"{name}.openlabel.json"
    if not document.exists():
        setup_path = work / f"{name}.setup.openlabel.json"
        write_document(setup_path, write_openlabel(setup))
        generate_document(setup_path, document, options)
    return document


def render_set(document: Path, out: Path, workers: int, frames=None) -> Path:
    """Render and label the document (``frames`` of it; None = all), export its ROIs (a re-run
    resumes); the ROI folder."""
    from usdscene import RunOptions, run_pipeline

    index = out / "exports" / "rois" / "index.csv"
    if not index.exists():
        options = RunOptions(frames=frames, exports=("rois",), workers=workers, report=False)
        run_pipeline(document, out, options, progress=False)
    return index.parent


def read_roi_index(name: str, folder: Path, classes) -> RoiSet:
    """The crops of an ``exports/rois`` folder with labels among ``classes``, labelled as
    ``usdscene export rois`` labelled them (the setup's ``roi_ignore`` leaves a seat holding only
    a passenger ``empty``). Crops with a label outside ``classes`` (a relation without a rule)
    are left out.
    """
    index = folder / "index.csv"
    if not index.is_file():
        raise UsageError(f"{index}: no ROI index (expected the exports/rois folder of usdscene export rois)")
    paths, labels = [], []
    with open(index, newline="") as handle:
        for row in csv.DictReader(handle):
            label = row["label"]
            if label in classes:
                paths.append(folder / row["path"])
                labels.append(label)
    return RoiSet(name, tuple(paths), tuple(labels))


def read_image_folder(name: str, folder: Path, classes) -> RoiSet:
    """Crops in one sub-folder per label (``DIR/correct/*.png``); every sub-folder must be a class."""
    if not folder.is_dir():
        raise UsageError(f"--real-test: {folder} is not a folder")
    subfolders = sorted(p for p in folder.iterdir() if p.is_dir())
    unknown = [p.name for p in subfolders if p.name not in classes]
    if unknown:
        raise UsageError(f"--real-test {folder}: folder(s) {', '.join(unknown)} are no label of the roi_rules "
                         f"(labels: {', '.join(classes)})")
    paths, labels = [], []
    for sub in subfolders:
        for path in sorted(sub.iterdir()):
            if path.suffix.lower() in IMAGE_SUFFIXES:
                paths.append(path)
                labels.append(sub.name)
    return RoiSet(name, tuple(paths), tuple(labels))


def check_set(roi_set: RoiSet, classes) -> None:
    """Refuse a set with no crop or with crops of one label only, giving the counts per label."""
    counts = {label: roi_set.counts().get(label, 0) for label in classes}
    shown = ", ".join(f"{label} {n}" for label, n in counts.items())
    if not roi_set.paths:
        raise UsageError(f"ROI set {roi_set.name!r} is empty ({shown}); a classifier needs crops of at least "
                         f"two labels")
    if sum(1 for n in counts.values() if n) < 2:
        raise UsageError(f"ROI set {roi_set.name!r} has crops of one label only ({shown}); a classifier needs "
                         f"at least two labels")


def subsample(roi_set: RoiSet, size: int, rng: np.random.Generator) -> RoiSet:
    """``size`` crops drawn without replacement (the label mix is the set's own)."""
    if size >= len(roi_set.paths):
        return roi_set
    keep = np.sort(rng.choice(len(roi_set.paths), size=size, replace=False))
    return RoiSet(roi_set.name, tuple(roi_set.paths[i] for i in keep), tuple(roi_set.labels[i] for i in keep))


def load_pixels(roi_set: RoiSet, size_px: int) -> np.ndarray:
    """Crops resized to ``size_px`` square, normalised with the ImageNet statistics.

    Returns:
        (N, 3, size_px, size_px) float32, RGB.
    """
    import cv2

    out = np.empty((len(roi_set.paths), 3, size_px, size_px), dtype=np.float32)
    for i, path in enumerate(roi_set.paths):
        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if image is None:
            raise UsageError(f"{path}: cannot read the image")
        image = cv2.resize(image, (size_px, size_px), interpolation=cv2.INTER_AREA)
        rgb = image[:, :, ::-1].astype(np.float32) / 255.0
        out[i] = ((rgb - MEAN_RGB) / STD_RGB).transpose(2, 0, 1)
    return out


# --------------------------------------------------------------------------------------------
# The model


def efficientnet_b0(num_classes: int):
    """EfficientNet-B0 with random initialisation, as a ``torch.nn.Module``.

    Written here on torch alone because torchvision's Linux wheels on PyPI are built against the
    CUDA build of torch and do not import beside the CPU build. Module and parameter names are
    torchvision's (``features.<stage>.<block>.block.<layer>``, ``classifier.1``), so
    ``torchvision.models.efficientnet_b0``'s ImageNet state dict loads (:func:`load_weights`).

    Input (N, 3, H, W) float32 (ImageNet-normalised RGB); output (N, num_classes) logits.
    """
    import torch
    from torch import nn

    def conv_bn(c_in, c_out, kernel, stride=1, groups=1, act=True):
        layers = [nn.Conv2d(c_in, c_out, kernel, stride, (kernel - 1) // 2, groups=groups, bias=False),
                  nn.BatchNorm2d(c_out)]
        if act:
            layers.append(nn.SiLU(inplace=True))
        return nn.Sequential(*layers)

    class SqueezeExcitation(nn.Module):
        def __init__(self, channels, squeezed):
            super().__init__()
            self.avgpool = nn.AdaptiveAvgPool2d(1)
            self.fc1 = nn.Conv2d(channels, squeezed, 1)
            self.fc2 = nn.Conv2d(squeezed, channels, 1)
            self.activation = nn.SiLU()
            self.scale_activation = nn.Sigmoid()

        def forward(self, x):
            scale = self.scale_activation(self.fc2(self.activation(self.fc1(self.avgpool(x)))))
            return x * scale

    class MBConv(nn.Module):
        def __init__(self, expand, kernel, stride, c_in, c_out, drop_prob):
            super().__init__()
            hidden = c_in * expand
            layers = [conv_bn(c_in, hidden, 1)] if expand != 1 else []
            layers += [conv_bn(hidden, hidden, kernel, stride, groups=hidden),
                       SqueezeExcitation(hidden, max(1, c_in // 4)),
                       conv_bn(hidden, c_out, 1, act=False)]
            self.block = nn.Sequential(*layers)
            self.residual = stride == 1 and c_in == c_out
            self.drop_prob = drop_prob

        def forward(self, x):
            y = self.block(x)
            if not self.residual:
                return y
            if self.training and self.drop_prob > 0.0:
                # Stochastic depth: drop the whole branch per sample, keep the expectation.
                keep = 1.0 - self.drop_prob
                mask = torch.empty((y.shape[0], 1, 1, 1), dtype=y.dtype, device=y.device).bernoulli_(keep)
                y = y * mask / keep
            return y + x

    class EfficientNetB0(nn.Module):
        def __init__(self):
            super().__init__()
            total = sum(stage[5] for stage in B0_STAGES)
            stages = [conv_bn(3, B0_STAGES[0][3], 3, 2)]
            done = 0
            for expand, kernel, stride, c_in, c_out, layers in B0_STAGES:
                blocks = []
                for i in range(layers):
                    blocks.append(MBConv(expand, kernel, stride if i == 0 else 1, c_in if i == 0 else c_out,
                                         c_out, B0_STOCHASTIC_DEPTH * done / total))
                    done += 1
                stages.append(nn.Sequential(*blocks))
            stages.append(conv_bn(B0_STAGES[-1][4], B0_HEAD_CHANNELS, 1))
            self.features = nn.Sequential(*stages)
            self.avgpool = nn.AdaptiveAvgPool2d(1)
            self.classifier = nn.Sequential(nn.Dropout(B0_DROPOUT, inplace=True),
                                            nn.Linear(B0_HEAD_CHANNELS, num_classes))
            for module in self.modules():
                if isinstance(module, nn.Conv2d):
                    nn.init.kaiming_normal_(module.weight, mode="fan_out")
                    if module.bias is not None:
                        nn.init.zeros_(module.bias)
                elif isinstance(module, nn.BatchNorm2d):
                    nn.init.ones_(module.weight)
                    nn.init.zeros_(module.bias)
                elif isinstance(module, nn.Linear):
                    bound = 1.0 / math.sqrt(module.out_features)
                    nn.init.uniform_(module.weight, -bound, bound)
                    nn.init.zeros_(module.bias)

        def forward(self, x):
            return self.classifier(torch.flatten(self.avgpool(self.features(x)), 1))

    return EfficientNetB0()


def load_weights(model, path: Path) -> int:
    """Load an ImageNet state dict (torchvision's ``efficientnet_b0``) except the classifier
    layer, whose class count differs. Returns the number of tensors loaded."""
    import torch

    if not path.is_file():
        raise UsageError(f"--weights: {path} is not a file")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # a pickle or zip error: not a state dict
        raise UsageError(f"--weights {path}: cannot read it as a PyTorch state dict ({exc})") from None
    own = model.state_dict()
    usable = {k: v for k, v in state.items() if k in own and own[k].shape == v.shape and not k.startswith("classifier")}
    backbone = [k for k in own if not k.startswith("classifier")]
    missing = [k for k in backbone if k not in usable]
    if missing:
        raise UsageError(f"--weights {path}: not an EfficientNet-B0 state dict ({len(missing)} of "
                         f"{len(backbone)} backbone tensors missing or of another shape, e.g. {missing[0]})")
    model.load_state_dict(usable, strict=False)
    return len(usable)


# --------------------------------------------------------------------------------------------
# Training and evaluation


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """The protocol: EfficientNet-B0, RMSprop, batch 40, 50 epochs (the paper's section 4.6.1).

    Attributes:
        epochs: passes over the training set.
        batch: crops per optimiser step.
        lr: RMSprop learning rate.
        size_px: input side in pixels (crops are resized to a square).
        weights: ImageNet state dict to start from; None = random initialisation.
        threads: torch intra-op threads.
    """

    epochs: int = 50
    batch: int = 40
    lr: float = 1e-3
    size_px: int = 32
    weights: Path | None = None
    threads: int = 1


def predict(model, pixels: np.ndarray, batch: int) -> np.ndarray:
    """Class index per crop, (N,) int64, from (N, 3, H, W) float32 pixels."""
    import torch

    model.eval()
    out = []
    with torch.no_grad():
        for start in range(0, len(pixels), batch):
            out.append(model(torch.from_numpy(pixels[start:start + batch])).argmax(1).numpy())
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def metrics(truth: np.ndarray, predicted: np.ndarray, classes) -> dict:
    """Accuracy, per-class recall, mean recall and confusion matrix (rows: truth, columns:
    prediction, in ``classes`` order) of (N,) class indices."""
    k = len(classes)
    confusion = np.zeros((k, k), dtype=np.int64)
    np.add.at(confusion, (truth, predicted), 1)
    support = confusion.sum(axis=1)
    recall = {c: (float(confusion[i, i] / support[i]) if support[i] else None) for i, c in enumerate(classes)}
    present = [r for r in recall.values() if r is not None]
    return {"accuracy": float(np.trace(confusion) / max(confusion.sum(), 1)),
            "mean_recall": float(np.mean(present)) if present else 0.0,
            "recall": recall, "confusion": confusion.tolist(), "support": support.tolist()}


def train_once(train_x: np.ndarray, train_y: np.ndarray, evals: dict, classes, config: TrainConfig,
               seed: int) -> dict:
    """Train one model from ``seed``; evaluate on every set of ``evals`` after each epoch.

    Args:
        train_x: (N, 3, S, S) float32 pixels; train_y: (N,) int64 class indices.
        evals: set name → (pixels, class indices).
        classes: label names in index order.
        config: the protocol.
        seed: seeds the initialisation, the shuffles, the flips and dropout.

    Returns:
        ``{"seed", "curves": {"train_loss", "train_accuracy", "<set>_accuracy": per epoch},
        "final": {set: metrics}, "seconds_per_step", "steps", "seconds"}``.
    """
    import torch

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    model = efficientnet_b0(len(classes))
    if config.weights is not None:
        load_weights(model, config.weights)
    # Keras's RMSprop (rho 0.9), the optimiser of the paper's Keras-era EfficientNet training.
    optimiser = torch.optim.RMSprop(model.parameters(), lr=config.lr, alpha=0.9, eps=1e-7)
    loss_fn = torch.nn.CrossEntropyLoss()
    curves: dict[str, list[float]] = {"train_loss": [], "train_accuracy": []}
    for name in evals:
        curves[f"{name}_accuracy"] = []
    step_seconds = 0.0
    steps = 0
    started = time.perf_counter()
    for _ in range(config.epochs):
        model.train()
        order = rng.permutation(len(train_x))
        losses, correct = [], 0
        for start in range(0, len(order), config.batch):
            idx = order[start:start + config.batch]
            x = train_x[idx].copy()
            flip = rng.random(len(idx)) < 0.5  # a mirrored seat region keeps its label
            x[flip] = x[flip][:, :, :, ::-1]
            xt, yt = torch.from_numpy(x), torch.from_numpy(train_y[idx])
            t0 = time.perf_counter()
            optimiser.zero_grad()
            logits = model(xt)
            loss = loss_fn(logits, yt)
            loss.backward()
            optimiser.step()
            step_seconds += time.perf_counter() - t0
            steps += 1
            losses.append(float(loss.detach()) * len(idx))
            correct += int((logits.argmax(1) == yt).sum())
        curves["train_loss"].append(sum(losses) / len(order))
        curves["train_accuracy"].append(correct / len(order))
        for name, (x, y) in evals.items():
            curves[f"{name}_accuracy"].append(float((predict(model, x, config.batch) == y).mean()))
    final = {name: metrics(y, predict(model, x, config.batch), classes) for name, (x, y) in evals.items()}
    return {"seed": seed, "curves": curves, "final": final, "steps": steps,
            "seconds_per_step": step_seconds / max(steps, 1), "seconds": time.perf_counter() - started}


# --------------------------------------------------------------------------------------------
# Reports


def summarise(values) -> dict:
    """Mean, sample standard deviation, min and max of a list of numbers."""
    a = np.asarray([v for v in values if v is not None], dtype=np.float64)
    if not len(a):
        return {"mean": None, "std": None, "min": None, "max": None}
    return {"mean": float(a.mean()), "std": float(a.std(ddof=1)) if len(a) > 1 else 0.0,
            "min": float(a.min()), "max": float(a.max())}


def results_table(results: dict) -> str:
    """Markdown: per training set and evaluation set, mean ± standard deviation over seeds."""
    classes = results["classes"]
    lines = []
    for eval_name in results["eval_sets"]:
        lines.append(f"Evaluated on `{eval_name}` ({results['eval_sizes'][eval_name]} crops); mean ± "
                     f"standard deviation over {len(results['seeds'])} seeds (min–max):")
        lines.append("")
        lines.append("| training set | accuracy | mean recall | " + " | ".join(f"recall {c}" for c in classes)
                     + " | s/step | training s |")
        lines.append("|---|---|---|" + "---|" * len(classes) + "---|---|")
        for name, run in results["trainings"].items():
            s = run["summary"][eval_name]

            def cell(stat):
                if stat["mean"] is None:
                    return "–"
                return f"{100 * stat['mean']:.1f} ± {100 * stat['std']:.1f} ({100 * stat['min']:.0f}–{100 * stat['max']:.0f})"

            lines.append(f"| {name} | {cell(s['accuracy'])} | {cell(s['mean_recall'])} | "
                         + " | ".join(cell(s['recall'][c]) for c in classes)
                         + f" | {run['seconds_per_step']['mean']:.3f} | {run['seconds']['mean']:.0f} |")
        lines.append("")
        lines.append("Confusion matrices (rows: truth, columns: prediction, summed over seeds; "
                     f"order {', '.join(classes)}):")
        lines.append("")
        for name, run in results["trainings"].items():
            total = np.sum([r["final"][eval_name]["confusion"] for r in run["runs"]], axis=0)
            lines.append(f"- {name}: " + " / ".join(" ".join(str(int(v)) for v in row) for row in total))
        lines.append("")
    return "\n".join(lines)


def draw_curves(results: dict, path: Path) -> None:
    """Training loss and accuracy on each evaluation set per epoch, one panel per training set
    (columns) and quantity (rows), one line per seed; written as PNG."""
    import cv2

    from usdscene.files import write_png_atomic

    names = list(results["trainings"])
    rows = ["train_loss", "train_accuracy"] + [f"{e}_accuracy" for e in results["eval_sets"]]
    pw, ph, margin = 360, 200, 44
    canvas = np.full((len(rows) * (ph + margin) + margin + 24, len(names) * (pw + margin) + margin, 3), 255,
                     np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    for r, quantity in enumerate(rows):
        series_all = [run["curves"][quantity] for name in names for run in results["trainings"][name]["runs"]]
        top = 1.0 if quantity.endswith("accuracy") else max(max(s) for s in series_all) * 1.05
        for c, name in enumerate(names):
            x0, y0 = margin + c * (pw + margin), margin + r * (ph + margin)
            cv2.rectangle(canvas, (x0, y0), (x0 + pw, y0 + ph), (0, 0, 0), 1)
            for frac in (0.25, 0.5, 0.75):
                y = int(y0 + ph * (1 - frac))
                cv2.line(canvas, (x0, y), (x0 + pw, y), (225, 225, 225), 1)
            cv2.putText(canvas, f"{name}: {quantity.replace('_', ' ')}", (x0, y0 - 8), font, 0.45, (0, 0, 0), 1,
                        cv2.LINE_AA)
            cv2.putText(canvas, f"{top:.2f}", (x0 - 40, y0 + 10), font, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
            cv2.putText(canvas, "0", (x0 - 14, y0 + ph), font, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
            for k, run in enumerate(results["trainings"][name]["runs"]):
                values = run["curves"][quantity]
                n = len(values)
                points = np.array([[x0 + pw * (i / max(n - 1, 1)), y0 + ph * (1 - min(v / top, 1.0))]
                                   for i, v in enumerate(values)], dtype=np.int32)
                cv2.polylines(canvas, [points], False, CURVE_COLOURS_BGR[k % len(CURVE_COLOURS_BGR)], 2, cv2.LINE_AA)
            if r == len(rows) - 1:
                cv2.putText(canvas, f"epoch 1..{results['config']['epochs']}", (x0 + pw // 2 - 40, y0 + ph + 16),
                            font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    x = margin
    for k, seed in enumerate(results["seeds"]):  # the legend: each seed's name in its line colour
        colour = CURVE_COLOURS_BGR[k % len(CURVE_COLOURS_BGR)]
        cv2.line(canvas, (x, canvas.shape[0] - 16), (x + 24, canvas.shape[0] - 16), colour, 3)
        cv2.putText(canvas, f"seed {seed}", (x + 30, canvas.shape[0] - 11), font, 0.45, colour, 1, cv2.LINE_AA)
        x += 110
    write_png_atomic(path, canvas)


# --------------------------------------------------------------------------------------------
# The experiment


def roi_classes(rules) -> tuple[str, ...]:
    """Labels of the ``roi_rules`` in first-seen order, then ``empty``."""
    return tuple(dict.fromkeys([*(str(v) for v in rules.values()), EMPTY_LABEL]))


def prepare_sets(args) -> tuple[dict[str, RoiSet], tuple[str, ...], dict]:
    """Generate and render (or take) the three training sets and the test set; equal sizes."""
    from usdscene import GenerateOptions

    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    train_setup = cabin_setup(args.cameras, args.places, args.width, args.samples)
    test_setup = cabin_setup(args.cameras, args.places, args.width, args.samples, test_lighting=True)
    classes = roi_classes(train_setup.roi_rules)
    taken = dict(args.rois)
    timings: dict[str, float] = {}
    sets: dict[str, RoiSet] = {}
    frames = args.frames
    for name in ("single-class", "balanced", "random", TEST_SET):  # single-class decides the frames
        if name in taken:
            sets[name] = read_roi_index(name, taken[name], classes)
            continue
        if name == TEST_SET:
            options = GenerateOptions(strategy="appearance", frames=args.test_frames, seed=args.test_seed,
                                      place_patterns=tuple(args.places), occupancy=args.test_occupancy,
                                      objects_per_frame=args.objects_per_frame)
            setup = test_setup
        else:
            strategy = name
            options = GenerateOptions(strategy=strategy, frames=None if strategy == "single-class" else frames,
                                      seed=args.data_seed + TRAIN_SETS.index(name),
                                      place_patterns=tuple(args.places), occupancy=args.occupancy,
                                      objects_per_frame=None if strategy == "single-class" else args.objects_per_frame)
            setup = train_setup
        started = time.perf_counter()
        document = generate_set(work, name, setup, options)
        rendered = None
        if name == "single-class":
            from usdscene import read_openlabel

            # balanced and random get as many frames as single-class renders: equal image counts.
            scene = read_openlabel(document)
            length = scene.frame_end - scene.frame_start + 1
            if frames is None:
                frames = length
            elif frames < length:  # evenly spread over its (class, relation) frames
                rendered = sorted({int(round(v)) for v in np.linspace(0, length - 1, frames)})
        folder = render_set(document, work / name, args.workers, rendered)
        timings[name] = time.perf_counter() - started
        sets[name] = read_roi_index(name, folder, classes)
    for roi_set in sets.values():
        check_set(roi_set, classes)
    size = min(len(sets[n].paths) for n in TRAIN_SETS)
    if args.rois_per_set:
        size = min(size, args.rois_per_set)
    rng = np.random.default_rng(args.data_seed)
    for name in TRAIN_SETS:
        sets[name] = subsample(sets[name], size, rng)
        check_set(sets[name], classes)
    if args.test_rois:
        sets[TEST_SET] = subsample(sets[TEST_SET], args.test_rois, rng)
        check_set(sets[TEST_SET], classes)
    return sets, classes, {"render_seconds": timings, "frames": frames}


def run_experiment(args) -> dict:
    """Datasets, 3 × seeds trainings, evaluations; writes results.json, results.md, curves.png."""
    torch = require_torch()
    torch.set_num_threads(args.threads)
    started = time.perf_counter()
    sets, classes, data_info = prepare_sets(args)
    evals_sets = {TEST_SET: sets[TEST_SET]}
    if args.real_test is not None:
        real = read_image_folder("real", args.real_test, classes)
        check_set(real, classes)
        evals_sets["real"] = real
    index = {c: i for i, c in enumerate(classes)}
    evals = {name: (load_pixels(s, args.size), np.array([index[l] for l in s.labels], dtype=np.int64))
             for name, s in evals_sets.items()}
    config = TrainConfig(epochs=args.epochs, batch=args.batch, lr=args.lr, size_px=args.size,
                         weights=args.weights, threads=args.threads)
    results = {"classes": list(classes), "seeds": list(args.seeds), "eval_sets": list(evals),
               "eval_sizes": {n: len(s.paths) for n, s in evals_sets.items()},
               "config": {**dataclasses.asdict(config), "weights": str(config.weights) if config.weights else None},
               "data": {**data_info, "counts": {n: s.counts() for n, s in sets.items()},
                        "cameras": list(args.cameras), "places": list(args.places), "width_px": args.width,
                        "samples": args.samples, "occupancy": args.occupancy,
                        "objects_per_frame": args.objects_per_frame,
                        "test_occupancy": args.test_occupancy},
               "trainings": {}}
    for name in args.train_sets:
        roi_set = sets[name]
        x = load_pixels(roi_set, args.size)
        y = np.array([index[l] for l in roi_set.labels], dtype=np.int64)
        runs = []
        for seed in args.seeds:
            runs.append(train_once(x, y, evals, classes, config, seed))
            if args.log:
                final = runs[-1]["final"][TEST_SET]
                print(f"{name} seed {seed}: test accuracy {final['accuracy']:.3f}, mean recall "
                      f"{final['mean_recall']:.3f}, {runs[-1]['seconds_per_step']:.3f} s/step", flush=True)
        summary = {ev: {"accuracy": summarise([r["final"][ev]["accuracy"] for r in runs]),
                        "mean_recall": summarise([r["final"][ev]["mean_recall"] for r in runs]),
                        "recall": {c: summarise([r["final"][ev]["recall"][c] for r in runs]) for c in classes}}
                   for ev in evals}
        results["trainings"][name] = {
            "size": len(roi_set.paths), "runs": runs, "summary": summary,
            "seconds_per_step": summarise([r["seconds_per_step"] for r in runs]),
            "seconds": summarise([r["seconds"] for r in runs])}
        results["seconds"] = time.perf_counter() - started
        write_reports(results, args.work)  # after each training set: a long run reports as it goes
    return results


def write_reports(results: dict, work: Path) -> None:
    """``results.json``, ``results.md`` (the table) and ``curves.png`` under ``work``."""
    from usdscene.files import write_json_atomic, write_text_atomic

    write_json_atomic(work / "results.json", results)
    write_text_atomic(work / "results.md", results_table(results))
    draw_curves(results, work / "curves.png")


def _named_folder(text: str) -> tuple[str, Path]:
    name, sep, folder = text.partition("=")
    if not sep or name not in (*TRAIN_SETS, TEST_SET):
        raise argparse.ArgumentTypeError(f"expected NAME=DIR with NAME one of {', '.join((*TRAIN_SETS, TEST_SET))}, "
                                         f"got {text!r}")
    return name, Path(folder)


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--work", type=Path, required=True, help="folder for documents, renders and results")
    p.add_argument("--epochs", type=_positive, default=50, help="epochs per training (default 50)")
    p.add_argument("--batch", type=_positive, default=40, help="batch size (default 40)")
    p.add_argument("--lr", type=float, default=1e-3, help="RMSprop learning rate (default 0.001)")
    p.add_argument("--size", type=_positive, default=32, help="input side in px (default 32; the paper: 224)")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds (default 0 1 2)")
    p.add_argument("--rois-per-set", type=int, default=400,
                   help="crops per training set, the same for all three (default 400; 0 = the smallest set's)")
    p.add_argument("--train-sets", nargs="+", choices=TRAIN_SETS, default=list(TRAIN_SETS),
                   help="which trainings to run (default all three)")
    p.add_argument("--weights", type=Path, default=None,
                   help="ImageNet state dict of torchvision's efficientnet_b0 to start from (default: random init)")
    p.add_argument("--real-test", type=Path, default=None,
                   help="real crops, one sub-folder per label (correct/, incorrect/, empty/), evaluated too")
    p.add_argument("--rois", type=_named_folder, action="append", default=[], metavar="NAME=DIR",
                   help="take a set's ROIs from an exports/rois folder instead of rendering it")
    p.add_argument("--cameras", nargs="+", default=["seats_L02", "seats_R02", "seats_L03", "seats_R03"],
                   help="cabin cameras to render (default: the 4 seat-area cameras over rows 03-06)")
    p.add_argument("--places", nargs="+", default=["seat_0[3-6]*", "bin_0[3-6]*", "aisle_0[3-6]"],
                   help="place patterns the generators use (default: rows 03-06, what the cameras see)")
    p.add_argument("--width", type=_positive, default=320, help="image width in px, height 3/4 (default 320)")
    p.add_argument("--samples", type=_positive, default=4, help="Cycles samples (default 4)")
    p.add_argument("--frames", type=_positive, default=6,
                   help="frames of balanced and random; as many of single-class's, evenly spread, are rendered "
                        "(default 6: 24 images, about 830 crops per set with the default cameras)")
    p.add_argument("--objects-per-frame", type=_positive, default=None,
                   help="generated objects per frame of balanced, random and the test document (default: the "
                        "generator's: what covering every combination in --frames needs, so few frames are full)")
    p.add_argument("--occupancy", type=float, default=0.3, help="seats taken in the training sets (default 0.3)")
    p.add_argument("--test-frames", type=_positive, default=6, help="frames of the test document (default 6)")
    p.add_argument("--test-occupancy", type=float, default=0.6, help="seats taken in the test set (default 0.6)")
    p.add_argument("--test-rois", type=int, default=400,
                   help="crops of the test set, drawn from its renders (default 400; 0 = all)")
    p.add_argument("--test-seed", type=int, default=101, help="generator seed of the test document (default 101)")
    p.add_argument("--data-seed", type=int, default=11, help="generator seed of the training documents (default 11)")
    p.add_argument("--workers", type=_positive, default=2, help="render worker processes (default 2)")
    p.add_argument("--threads", type=_positive, default=1,
                   help="torch threads (default 1: faster than 2 on a busy 2-core machine; try 2 on an idle one)")
    p.add_argument("--quiet", dest="log", action="store_false", help="no line per finished training")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    from usdscene import UsdSceneError

    try:
        results = run_experiment(args)
    except UsageError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    except UsdSceneError as exc:
        for problem in exc.problems:
            print(f"{PROG}: error: {problem}", file=sys.stderr)
        return 1
    print(results_table(results))
    print(f"wrote {args.work / 'results.json'}, {args.work / 'results.md'}, {args.work / 'curves.png'} "
          f"({results['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
