"""The learner's health on /diagnostics: its activity, its last training, the model it announced
(pure)."""
from __future__ import annotations

from flexarm_core.health_report import ERROR, OK, WARN, Status, status
from flexarm_deflection.model_summary import ModelSummary


def learner_statuses(node: str, progress: str, training: bool,
                     dataset: tuple[str, int] | None, trained: tuple[bool, str] | None,
                     announced: ModelSummary | None, announce_error: str) -> list[Status]:
    """The learner's health:

    * ``<node>: activity``, always OK: idle, the collection's or refresh's ``progress``
      ("collecting k of n ...") and/or training; the dataset last collected into and its size.
    * ``<node>: training``: the last training's outcome; WARN when it failed (no new model,
      the previous one stays active), OK otherwise (also before any training).
    * ``<node>: model``: the model last announced on /learner/model; ERROR when the current
      model record could not be announced (damaged, unloadable: the compensator has none),
      WARN when the model was made for another payload or arm (its warning), else OK.
    """
    doing = '; '.join(filter(None, [progress, 'training' if training else ''])) or 'idle'
    activity = status(node, 'activity', OK, doing, {
        'activity': doing, 'dataset': dataset[0] if dataset else '',
        'dataset samples': dataset[1] if dataset else 0})
    if trained is None:
        training_status = status(node, 'training', OK, 'no training since start')
    else:
        succeeded, text = trained
        training_status = status(node, 'training', OK if succeeded else WARN, text,
                                 {'succeeded': succeeded})
    values = {'version': announced.version if announced else '',
              'kind': announced.kind if announced else '',
              'dataset': announced.dataset if announced else '',
              'warning': announced.warning if announced else ''}
    if announce_error:
        model = status(node, 'model', ERROR, f'no model announced: {announce_error}', values)
    elif announced is None:
        model = status(node, 'model', OK, 'no model yet: collect samples and train', values)
    else:
        model = status(node, 'model', WARN if announced.warning else OK,
                       f'model v{announced.version} ({announced.kind}) announced'
                       + (f': {announced.warning}' if announced.warning else ''), values)
    return [activity, training_status, model]
