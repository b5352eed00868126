"""Uses of the SLDS (Pavlovic et al. 1999, section 4): classification, synthesis, interpolation.

The modules, each one part of the paper's section 4:

* :mod:`.classification` (section 4.1, Fig. 3): one SLDS per activity (walk,
  run) learned from the training clips, joined with a block transition
  matrix; the Viterbi switch sequence of a footnote-4 test sequence names the
  activity of every frame; footnote 5's error.
* :mod:`.features`: what the models see (the angles, centred angles, velocities).
* :mod:`.settings`: the protocol's constants, the candidate settings and the
  cross-validation's choices.
* :mod:`.scoring`: a grid of settings scored on shared test sequences, one fit
  per parameter subset and features, in forked processes.
* :mod:`.cross_validation`: the settings chosen by leave-one-group-out CV on
  the training split (``slds select``).
* :mod:`.splits`: the error of fixed settings per held-out style and person
  (``slds splits``).
* :mod:`.interpolation` (Fig. 6): a gap of a test person's walking clip filled
  by smoothing with missing measurements, against linear and cubic-spline
  interpolation of the same gap.
* :mod:`.figures`: Figs. 3, 5 (noise-driven sampling of a learned model,
  :func:`baselines.priors.slds.synthesize`) and 6.
* :mod:`.data`: loading the clips, the activities' labels, the person split.

Every public name of these modules is importable from this package.

Command line: ``humotion-gym slds classify|select|splits|interpolate|figures``
(:mod:`baselines.cli.slds`). ``classify`` refuses a file reached by both
``--train`` and ``--test``; different files of one clip id are split by person
(:func:`split_train_test`). Without ``--labels`` the activities are walk and
run, Bandai-Namco set 1's ``dash`` counted as run (:data:`LABEL_ALIASES`).

Settings chosen by cross-validation (:func:`select_classifier_settings`,
``slds select``, training split only): the parameter subset, the switch
probability, the features (:func:`feature_transform`) and the extra noise the
decoder assumes are chosen by leave-one-group-out CV, a group being a
Bandai-Namco style or a training person (:func:`cv_groups`), scored by
:func:`criterion_scores`. :data:`CLASSIFY_PARAMS`, :data:`CLASSIFY_SWITCH_PROB`,
:data:`CLASSIFY_FEATURES` and :data:`CLASSIFY_EXTRA_NOISE_DEG` are its choices
on ``../shared/mocap``.

The measured errors of these commands on ``../shared/mocap`` are in docs/priors.md.
"""

from __future__ import annotations

from baselines.experiments.pavlovic1999.classification import (  # noqa: F401
    ClassificationResult,
    TestSequence,
    build_test_sequences,
    classify,
    fit_activities,
    fit_activity_models,
    run_classification,
    sequence_features,
    with_measurement_noise,
)
from baselines.experiments.pavlovic1999.cross_validation import (  # noqa: F401
    SelectionResult,
    check_training_only,
    criterion_scores,
    cv_groups,
    group_kind,
    held_out_groups,
    select_classifier_settings,
)
from baselines.experiments.pavlovic1999.data import (  # noqa: F401
    activity_clips,
    default_motions,
    load_motions,
    person_split,
    split_train_test,
)
from baselines.experiments.pavlovic1999.features import (  # noqa: F401
    FEATURES_HELP,
    assumed_noise,
    feature_noise,
    feature_transform,
    motion_features,
    parse_features,
    running_mean,
)
from baselines.experiments.pavlovic1999.figures import (  # noqa: F401
    plot_interpolation,
    plot_segmentation,
    plot_synthesis,
)
from baselines.experiments.pavlovic1999.interpolation import (  # noqa: F401
    InterpolationResult,
    interpolate_gap,
    run_interpolation,
)
from baselines.experiments.pavlovic1999.scoring import (  # noqa: F401
    SettingScores,
    run_jobs,
    score_fits,
)
from baselines.experiments.pavlovic1999.settings import (  # noqa: F401
    BLEND_FRAMES,
    CANDIDATE_EXTRA_NOISE_DEG,
    CANDIDATE_FEATURES,
    CANDIDATE_PARAMS,
    CANDIDATE_SWITCH_PROBS,
    CLASSIFY_EXTRA_NOISE_DEG,
    CLASSIFY_FEATURES,
    CLASSIFY_INDEX,
    CLASSIFY_LABELS,
    CLASSIFY_PARAMS,
    CLASSIFY_SWITCH_PROB,
    CLIPS_PER_SEQUENCE,
    CV_CRITERIA,
    GAP,
    LABEL_ALIASES,
    LEG_PARAMS,
    NOISE_STD,
    OLD_CLASSIFY_PARAMS,
    OLD_CLASSIFY_SWITCH_PROB,
    ClassifierSetting,
    default_settings,
    param_indices,
    setting_name,
)
from baselines.experiments.pavlovic1999.splits import (  # noqa: F401
    SplitRow,
    check_splits,
    evaluate_splits,
    splits_table,
)
from baselines.priors import slds  # noqa: F401
