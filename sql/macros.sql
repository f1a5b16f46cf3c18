-- Temporary macros installed on every mocapdb.connect (they call Python UDFs,
-- which exist only on connections where Python registered them). Parameter
-- names differ from every column name the bodies read (DuckDB rejects the
-- clash), and table aliases inside are prefixed mocap_ so that an argument such
-- as m.motion_id cannot be captured by an alias of the body (macros expand
-- textually).

-- Δ of a class template against a motion: one DOUBLE per 30 Hz frame,
-- inf where no template match can end.
CREATE OR REPLACE TEMP MACRO mt_distance(motion, cls, model := 'default') AS
    mocap_mt_distance(
        (SELECT list(mocap_f.bits ORDER BY mocap_f.frame) FROM features mocap_f WHERE mocap_f.motion_id = motion),
        (SELECT mocap_u.c FROM model_payload mocap_p, unnest(mocap_p.classes) AS mocap_u(c)
         WHERE mocap_p.model_name = model AND mocap_u.c.class = cls),
        cls, model);

-- Labelled segments of a motion: LIST(STRUCT(label, start_frame, end_frame, cost, start_s, end_s)),
-- frames 1-based at 30 Hz. A NULL tau uses each class's τ; a NULL keyframes uses
-- the model's keyframe queries when it has them.
CREATE OR REPLACE TEMP MACRO annotate(motion, model := 'default', tau := NULL, keyframes := NULL) AS
    mocap_annotate(
        (SELECT list(mocap_f.bits ORDER BY mocap_f.frame) FROM features mocap_f WHERE mocap_f.motion_id = motion),
        (SELECT mocap_m.fps FROM motions mocap_m WHERE mocap_m.motion_id = motion),
        (SELECT {model_name: mocap_p.model_name, fingerprint: mocap_p.fingerprint, labels: mocap_p.labels,
                 classes: mocap_p.classes}
         FROM model_payload mocap_p WHERE mocap_p.model_name = model),
        model, tau::DOUBLE, keyframes::BOOLEAN);
