"""The ``tracker.identity`` section: appearance, re-identification and the roster."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field

from openptrack_py.config.base import StrictModel


class IdentityConfig(StrictModel):
    """Who each track is: appearance in association, re-identification, named people.

    Off by default; ``enabled: true`` turns every part on with these settings. Nothing
    here is a similarity threshold: how alike two signatures of one person are, and of
    two people, is learned online from the tracker's own unambiguous associations, so
    the same settings hold whether people dress alike or not.

    Parameters
    ----------
    enabled : bool
        Use the identity role (otherwise tracks carry no ``stable_id`` or name).
    appearance_weight : float
        Weight of the colour signature's log-likelihood ratio in the association cost
        (the motion term's weight is 1; the childcare tracking paper's weighted
        combination of motion, colour and face likelihoods).
    embedding_weight : float
        Weight of an identity embedding's (``face``) log-likelihood ratio, multiplied by
        the embedding's own confidence.
    height_weight : float
        Weight of the height's log-likelihood ratio (a soft biometric: how tall a person
        is tells little alone, but adds to colour what colour cannot tell apart); each
        sensor's height error (against the other sensors' heights of the same people)
        is learned and removed first. 0 leaves heights out (none is learned or
        compared); on the ``realistic`` held-out runs 1 raised mean IDF1 on five of six
        scenarios, kept as many returns and put the right name on 96-98 % of a
        registered classroom's frames (``docs/evaluation.md``).
    max_llr : float
        Largest absolute log-likelihood ratio one observation contributes.
    min_observations : int
        Clean observations a track's appearance model needs before it is used.
    model_rate : float
        Least weight of a new observation in a track's appearance model, the one
        association compares detections with: the model is the mean of its clean
        observations, forgetting slowly once it has ``1 / model_rate`` of them
        (DeepSORT keeps a gallery of the last 100 appearance features per track; 0.01
        is that memory): how the person looks now, under the sensors that see them now.
    visit_rate : float
        The same for the colour model a lost track leaves in the pool: how the person
        looked over their visit (a roster entry's colours take the other: how they
        look now).
        0.002 keeps 500 clean observations, with three sensors at 15-30 Hz several
        seconds and several sensors' colour casts; a memory of 100 describes only the
        last one to three seconds before they left, walking away under the door's
        sensor. Heights have this memory only (one model, for association and the
        pool): a height does not change with the light, and a person seen lower for a
        moment (bending to pick up a bag on the way out) must not pool the stoop.
    clean_min_confidence : float
        Only detections at least this confident, whose image box overlaps no other
        detection's, teach a track's appearance (a half-hidden person's colours are
        mixed with the one in front).
    pool_s : float
        How long a lost confirmed identity waits in the pool to be recognised again.
    reid_window_s : float
        A new track may take back a pooled identity during its first this-many seconds.
    reid_max_speed_mps : float
        A pooled identity may only be taken by a track that starts where its person
        could have walked to at this speed since it was lost (plus ``reid_margin_m``).
    reid_margin_m : float
        See ``reid_max_speed_mps``.
    evidence_per_observation : float
        Share of an observation's log-likelihood ratio that counts as independent
        evidence for a name (successive frames of one person are strongly correlated).
    link_evidence : float
        Accumulated log-likelihood ratio a track needs for a registered name; it must
        also beat the second best by ``link_margin``. Two tracks whose models differ by
        ``link_margin`` are two people; two tracks that met (came within
        ``share_distance_m``) and, once apart, look more like each other's identity
        than their own by ``link_margin`` (their mean log-likelihood ratios summed)
        exchanged their people there, and take each other's identity back
        (:mod:`~openptrack_py.tracking.identity.swaps`).
    link_margin : float
        See ``link_evidence``.
    reid_min_s : float
        A young track is observed this long before it may take a pooled identity. 0:
        as soon as it is confirmed and its evidence passes the tests below (a wrong link
        is undone by later evidence; a wait only delays the right ones).
    reid_mean_llr : float
        Least mean log-likelihood ratio of its observations against the pooled identity
        (a mean, not a sum: frames are not independent, and a sum would soon pass any
        threshold for a stranger who merely dresses alike). Colours and identity
        embeddings are averaged each over the observations that carry them and the two
        means added (independent cues).
    reid_margin : float
        Least lead of that mean over every other young track that could be the same
        pooled identity.
    reid_min_posterior : float
        Least probability that the track is the pooled identity, given its evidence
        against every pooled identity it could be and the share of new tracks that turn
        out to be returns, estimated online (:mod:`~openptrack_py.tracking.identity.returns`):
        the more look-alikes in the pool and the rarer returns are at the site, the more
        evidence a link needs. 0.5 is the Bayes decision when a wrong link costs as much
        as a missed one.
    unlink_evidence : float
        A link is undone when the mean falls to this (later observations contradict
        it), and the identity returns to the pool.
    share_max_s : float
        Two tracks known to be two people may share one detection (people standing so
        close they come out as one blob) for at most this long after they were last
        detected as two people in one sensor frame.
    share_distance_m : float
        ... and only while the two tracks are at most this far apart (two people side
        by side in one blob: each within a body width of its centroid).
    roster_file : Path or None
        YAML file of registered people (``openptrack roster``); reloaded when it changes.
    """

    enabled: bool = False
    appearance_weight: float = Field(1.0, ge=0.0, le=10.0)
    embedding_weight: float = Field(1.0, ge=0.0, le=10.0)
    height_weight: float = Field(1.0, ge=0.0, le=10.0)
    max_llr: float = Field(3.0, gt=0.0, le=20.0)
    min_observations: int = Field(3, ge=1, le=1000)
    model_rate: float = Field(0.01, gt=0.0, le=1.0)
    visit_rate: float = Field(0.002, gt=0.0, le=1.0)
    clean_min_confidence: float = Field(0.5, ge=0.0, le=1.0)
    pool_s: float = Field(180.0, ge=0.0, le=86400.0)
    reid_window_s: float = Field(10.0, gt=0.0, le=3600.0)
    reid_max_speed_mps: float = Field(2.5, gt=0.0, le=20.0)
    reid_margin_m: float = Field(1.0, ge=0.0, le=100.0)
    evidence_per_observation: float = Field(0.2, gt=0.0, le=1.0)
    link_evidence: float = Field(3.0, gt=0.0, le=100.0)
    link_margin: float = Field(2.0, ge=0.0, le=100.0)
    reid_min_s: float = Field(0.0, ge=0.0, le=600.0)
    reid_mean_llr: float = Field(1.0, gt=0.0, le=20.0)
    reid_margin: float = Field(0.5, ge=0.0, le=20.0)
    reid_min_posterior: float = Field(0.5, gt=0.0, lt=1.0)
    unlink_evidence: float = Field(0.0, le=1.0, ge=-20.0)
    share_max_s: float = Field(60.0, ge=0.0, le=3600.0)
    share_distance_m: float = Field(0.6, ge=0.0, le=5.0)
    roster_file: Path | None = None
