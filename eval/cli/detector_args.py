"""Helpers the detector commands share: the operating confidence, the --seed check, detection with --option."""

from __future__ import annotations

from poi.config import DetectorConfig

OPERATING_CONF = DetectorConfig().conf


def _refuse_training_seed(args) -> None:
    """Refuse fresh scenes from a --seed the detector or its label model was trained on (the seeds
    ``poibench train`` and ``train-labels`` write into the model's metadata)."""
    from eval.detector.quality import DetectorQualityError, model_training_seeds
    from poi.detectors import is_team_detector

    for model in (args.model, args.label_model):
        if model is None or is_team_detector(model):
            continue  # a Python detector carries no training metadata
        if args.seed in model_training_seeds(model):
            raise DetectorQualityError(
                f"{model} was trained on scenes from seed {args.seed}; evaluate on another --seed"
            )


def _detect(args, images, conf):
    from eval.detector.quality import detect_all
    from eval.progress import progress_bar

    with progress_bar(total=len(images), desc="detect", unit="img", quiet=args.quiet) as bar:
        return detect_all(
            args.model,
            images,
            conf,
            progress=bar.update,
            label_model=args.label_model,
            options=_options(args),
        )


def _options(args) -> dict:
    """``--option KEY=VALUE`` items as a Python detector's keyword arguments; checks the detector
    names something (its module imports) before any scene is rendered."""
    from eval.cli.run import check_detector
    from eval.detector.quality import DetectorQualityError
    from poi.core.loader import safe_load
    from poi.detectors import is_team_detector
    from poi.detectors.plugins import check_python_detector

    team = is_team_detector(args.model)
    if team:
        check_detector(args.model)
    elif args.option:
        raise DetectorQualityError(f"--option is for a Python detector; {args.model} is an ONNX model")
    out = {}
    for item in args.option:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise DetectorQualityError(f"--option {item!r}: expected KEY=VALUE, e.g. conf=0.3")
        out[key.strip()] = safe_load(text, f"--option {key.strip()}", error=DetectorQualityError)
    if team:
        check_python_detector(args.model, out)
    return out
