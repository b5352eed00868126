"""Coarse activity labels from free-text descriptions and file names.

One label per clip, from CMU's trial description, a Bandai-Namco content name or
a user's file name. The rules are ordered; the first that matches wins, so the
order encodes which activity a mixed description counts as. The text is read as
words: CamelCase and digits are split (``RunningStraight`` -> ``running
straight``, ``Walk8`` -> ``walk 8``) and ``_ . -`` become spaces.

The order (the table of ``docs/data.md``, "Labels") and its reasons: first
``calibration`` (range of motion, T-pose...: never tracked as an activity), then
``other`` for texts that describe no motion ("Unknown", "clean", "bad AMC"),
then a category prefix (``dance - ...``, ``basketball - ...``), then CMU's
"(human subject)" mark of acted animals (so "dancing bear (human subject)" is a
pantomime, not a dance); then :data:`_RULES` in order: acrobatics before jump
and dance, dance before walk ("dance - Egyptian walk"), walk before run ("walk
to run" and "walking, running, jumping" are walks: the walking tasks want every
clip that starts walking), then run, jump, fight, sports, reach (motion of the
arms), everyday and pantomime (animals and characters without the mark).

Anything else is ``other``. :func:`activity_label` is what the library uses;
:data:`ACTIVITY_LABELS` lists every label it can return.
"""

from __future__ import annotations

import re

#: Every label :func:`activity_label` can return.
ACTIVITY_LABELS: tuple[str, ...] = (
    "walk", "run", "jump", "dance", "fight", "sports", "acrobatics", "reach",
    "everyday", "pantomime", "calibration", "other",
)  # fmt: skip


def _any(*words: str) -> str:
    """A regex matching any of the words (each may be a regex) at word starts."""
    return r"\b(?:" + "|".join(words) + ")"


_CALIBRATION = re.compile(
    _any(
        r"range of motion\b", r"motor ?cycle\b", r"t ?pose\b", r"calibration\b",
        r"static pose\b", r"dynamic calibration\b",
    )
)  # fmt: skip
_NOTHING = re.compile(
    r"^(?:unknown|clean|cleaned|bad amc|no movie|movie and trial dont match|lost marker|)$"
)
_PREFIX = re.compile(r"^([a-z ]+?) - ")
_PREFIX_LABELS = {
    "dance": "dance",
    "static dance pose": "dance",
    "basketball": "sports",
    "soccer": "sports",
    "football": "sports",
    "nursery rhyme": "pantomime",
    "acrobatics": "acrobatics",
}
_HUMAN_SUBJECT = re.compile(r"\(human subject\)")

_RULES: tuple[tuple[str, re.Pattern[str]], ...] = (
    ("acrobatics", re.compile(_any(
        r"cartwheels?\b", r"flips?\b", r"flp\b", r"back ?flips?\b", r"hand ?stands?\b",
        r"hand spring", r"summersult", r"somersault", r"helicopter\b", r"kick ?flip",
        r"wide leg roll", r"acrobatic", r"balance beam", r"hang on ropes",
    ))),
    ("dance", re.compile(_any(
        r"danc", r"salsa\b", r"charleston\b", r"lindy", r"ballet", r"ballerina",
        r"pirouette", r"arabesque", r"moonwalk", r"tai chi\b", r"break ?dance",
    ))),
    ("walk", re.compile(_any(
        r"walk", r"wander", r"strid", r"march", r"stroll", r"hobbl", r"limp",
        r"sneak", r"creep", r"pacing\b", r"navigate\b", r"mummy", r"digital 8\b",
        r"slope\b",
    ))),
    ("run", re.compile(_any(r"run", r"jog", r"sprint", r"dash\b"))),
    ("jump", re.compile(_any(r"jump", r"hop", r"leap", r"bound\b"))),
    ("fight", re.compile(_any(
        r"punch", r"strike\b", r"boxing\b", r"boxer", r"kick", r"sword", r"fight",
        r"karate", r"martial", r"attack", r"blocks?\b", r"wrestl", r"bassai\b",
        r"empi\b", r"gedanbarai\b", r"heiansyodan\b", r"mawashigeri\b", r"oiduki\b",
        r"syutouuke\b", r"yokogeri\b", r"slash\b", r"lunges?\b",
    ))),
    ("sports", re.compile(_any(
        r"basketball", r"soccer", r"football", r"golf", r"putt\b", r"baseball",
        r"pitch\b", r"bunt\b", r"frisbee", r"swim", r"stroke\b", r"butterfly\b",
        r"free style\b", r"skateboard", r"dribbl", r"lay ?up\b", r"shoot", r"throw",
        r"catch", r"toss", r"rowing\b", r"weight lifting", r"bow and arrow",
        r"fishing\b", r"swing\b",
    ))),
    ("reach", re.compile(_any(
        r"reach", r"wave\b", r"waving\b", r"point\b", r"signals?\b", r"gesture",
        r"conduct", r"direct traffic", r"high five\b", r"low five\b", r"shake hands",
        r"hand shake", r"shaking hands", r"peek ?a ?boo", r"airplane\b", r"bye",
        r"guide\b", r"call\b", r"respond\b", r"hand motions", r"flexing\b",
    ))),
    ("everyday", re.compile(_any(
        r"sit", r"stand", r"drink", r"eat", r"wash", r"wip", r"sweep", r"mop\b",
        r"clean", r"bend", r"scoop", r"lift", r"pick", r"carry", r"suitcase", r"push",
        r"pull", r"drag", r"climb", r"ladder", r"stair", r"steps?\b", r"sidestep",
        r"squat", r"stretch", r"yawn", r"laugh", r"cry", r"put", r"brush", r"comb",
        r"shav", r"typ", r"vacuum", r"rak", r"dig", r"plant", r"sew", r"chop",
        r"slic", r"mix", r"dough", r"coffee", r"mug\b", r"phone", r"dial", r"paint",
        r"hammer", r"saw", r"screw", r"unscrew", r"bolt", r"nail", r"box\b",
        r"umbrella", r"rope", r"lay", r"get up", r"getting up", r"crawl", r"bow\b",
        r"curtsey", r"shrug", r"mope", r"yoga", r"tiptoe", r"duck", r"look", r"search",
        r"pok", r"investigat", r"wait", r"idle", r"story", r"conversation",
        r"quarrel", r"comfort", r"shelter", r"stumble", r"violence", r"resist",
        r"hold", r"hang", r"balanc", r"lean", r"fidget", r"grab", r"fix hair",
        r"adjust hair", r"driving", r"piano", r"violin", r"drum", r"teaching",
        r"smok", r"chug", r"sip", r"bang", r"sun salutation", r"relax", r"fall",
        r"slip", r"turn", r"step over", r"vignettes", r"moving\b", r"stepp", r"writ",
        r"swat", r"arguing\b",
    ))),
    ("pantomime", re.compile(_any(
        r"bear\b", r"chicken", r"elephant", r"monkey", r"mouse\b", r"chip ?munk",
        r"chip monk", r"prairie dog", r"dog\b", r"snake", r"t rex\b", r"tyrannosaurus",
        r"dinosaur", r"fish\b", r"bird\b", r"cat\b", r"cow\b", r"tiger", r"penguin",
        r"horse", r"gorilla", r"panther", r"whale", r"genie", r"devil", r"superhero",
        r"robot", r"zombie", r"ghost", r"dragon", r"alaska", r"teapot", r"cock robin",
        r"mickey", r"alien", r"cold\b", r"freezing", r"happy", r"sad\b", r"scared",
        r"upset", r"angry", r"proud", r"tired",
    ))),
)  # fmt: skip


def words(text: str) -> str:
    """Lower-case words of a description or name: CamelCase, digits and ``_.-`` split.

    Example:
        >>> words("RunningTighterRight_001")
        'running tighter right 001'
    """
    text = re.sub(r"([a-z])([A-Z])", r"\1 \2", text)
    text = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1 \2", text)
    text = re.sub(r"([A-Za-z])(\d)", r"\1 \2", text)
    text = re.sub(r"(\d)([A-Za-z])", r"\1 \2", text)
    text = re.sub(r"[_.]+", " ", text).lower()
    text = re.sub(r"(?<=[a-z])-(?=[a-z])", " ", text)  # high-five -> high five
    return re.sub(r"\s+", " ", text).strip()


def says_nothing(description: str) -> bool:
    """True for a description that names no motion ("Unknown", "clean", "bad AMC", "")."""
    return _NOTHING.match(words(description)) is not None


def activity_label(description: str) -> str:
    """The coarse activity label of a description (rules in the module docstring).

    Args:
        description: CMU's trial description, a content name or a file name.

    Returns:
        One of :data:`ACTIVITY_LABELS`.

    Example:
        >>> [activity_label(d) for d in ("walk on uneven terrain", "run/jog", "JumpForward")]
        ['walk', 'run', 'jump']
    """
    text = words(description)
    if _CALIBRATION.search(text):
        return "calibration"
    if _NOTHING.match(text):
        return "other"
    prefix = _PREFIX.match(text)
    if prefix and prefix[1] in _PREFIX_LABELS:
        return _PREFIX_LABELS[prefix[1]]
    if _HUMAN_SUBJECT.search(text):
        return "pantomime"
    for label, pattern in _RULES:
        if pattern.search(text):
            return label
    return "other"
