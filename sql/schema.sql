-- mocapdb schema: plain tables, created on every read-write connect (IF NOT
-- EXISTS), so a database written by an older mocapdb gains new objects.
-- Frames stored here are 1-based and inclusive, like the HDM05 annotations;
-- `frame` in `features` counts 30 Hz frames (native frame 4·frame − 3).

CREATE SEQUENCE IF NOT EXISTS motion_id_seq START 1;

CREATE TABLE IF NOT EXISTS motions (
    motion_id        INTEGER PRIMARY KEY DEFAULT nextval('motion_id_seq'),
    name             VARCHAR NOT NULL,          -- file stem, e.g. 86_09
    source_path      VARCHAR NOT NULL,
    format           VARCHAR NOT NULL,          -- amc, bvh
    sha256           VARCHAR NOT NULL,          -- of the source file's bytes
    skeleton_sha256  VARCHAR,                   -- of the ASF's bytes (AMC only)
    source_fps       DOUBLE NOT NULL,           -- native rate, usually 120
    fps              DOUBLE NOT NULL,           -- rate of `features`: 30 for every source rate
    n_source_frames  INTEGER NOT NULL,
    n_frames         INTEGER NOT NULL,          -- rows in `features`: floor((n_source_frames - 1) * 30 / source_fps) + 1
    skeleton         VARCHAR,
    skeleton_path    VARCHAR,
    reader_options   VARCHAR,                   -- JSON: the reader's options (joint_map, marker_map), to re-read the source
    ingested_at      TIMESTAMP NOT NULL DEFAULT current_timestamp,
    UNIQUE (sha256, skeleton_sha256)
);

-- databases from before reader_options
ALTER TABLE motions ADD COLUMN IF NOT EXISTS reader_options VARCHAR;

-- One row per 30 Hz frame: the 40 relational features packed into one word,
-- bit k-1 = feature k (FEATURES.md §0 order; see the view feature_flags).
CREATE TABLE IF NOT EXISTS features (
    motion_id  INTEGER NOT NULL,
    frame      INTEGER NOT NULL,
    bits       UBIGINT NOT NULL
);

-- Class models: several live side by side, told apart by `model`.
CREATE TABLE IF NOT EXISTS models (
    model        VARCHAR PRIMARY KEY,
    description  VARCHAR,
    source       VARCHAR,                  -- how it was made (training data, command)
    fingerprint  VARCHAR NOT NULL,         -- changes whenever the model's rows change
    created_at   TIMESTAMP NOT NULL DEFAULT current_timestamp,
    shipped      BOOLEAN NOT NULL DEFAULT false,  -- installed from the package (kept up to date)
    margin       DOUBLE NOT NULL DEFAULT 0,  -- frames whose best label wins by less stay unlabelled
    concurrent_labels VARCHAR[]            -- labels annotated beside the others (turn beside move)
);
-- databases from before `shipped`: the packaged default model was loaded on
-- first use and said so in its source
ALTER TABLE models ADD COLUMN IF NOT EXISTS shipped BOOLEAN DEFAULT false;
UPDATE models SET shipped = true
WHERE NOT shipped AND model = 'default' AND source LIKE '%keyframe queries: GA from folder%hdm05_cut';
-- databases from before the segment filters (issue 11): no margin, no minimum length
ALTER TABLE models ADD COLUMN IF NOT EXISTS margin DOUBLE DEFAULT 0;
-- databases from before concurrent labels (issue 25): every label competes (the paper)
ALTER TABLE models ADD COLUMN IF NOT EXISTS concurrent_labels VARCHAR[];

-- One row per fine class: its coarse label (squat1Reps -> exercise), the
-- quantization threshold δ of its template, its hit threshold τ and the
-- shortest segment its label keeps through it.
CREATE TABLE IF NOT EXISTS classes (
    model     VARCHAR NOT NULL,
    class     VARCHAR NOT NULL,
    class_id  INTEGER NOT NULL,            -- order of Δ rows and hits (1-based)
    label     VARCHAR NOT NULL,
    label_id  INTEGER NOT NULL,            -- label order: ties in Δmin go to the lowest
    delta     DOUBLE NOT NULL,
    tau       DOUBLE NOT NULL,
    n_clips   INTEGER,
    min_frames INTEGER NOT NULL DEFAULT 0, -- 30 Hz frames; 0 = no minimum (the paper)
    PRIMARY KEY (model, class)
);
ALTER TABLE classes ADD COLUMN IF NOT EXISTS min_frames INTEGER DEFAULT 0;

-- Motion templates, one row per template column (30 Hz template frame):
-- the real-valued template (40 values in [0, 1]) and its weight, and the
-- quantized column as (mask, value) words: mask bit = not a wildcard.
CREATE TABLE IF NOT EXISTS templates (
    model   VARCHAR NOT NULL,
    class   VARCHAR NOT NULL,
    col     INTEGER NOT NULL,              -- 1-based
    mask    UBIGINT NOT NULL,
    value   UBIGINT NOT NULL,
    weight  DOUBLE NOT NULL,               -- weight of the quantized column
    real    DOUBLE[],                      -- real-valued template column (NULL if unknown)
    real_weight DOUBLE,
    PRIMARY KEY (model, class, col)
);

-- Keyframe queries (one per class and model) and their keyframes.
CREATE TABLE IF NOT EXISTS keyframe_queries (
    model            VARCHAR NOT NULL,
    class            VARCHAR NOT NULL,
    n_keyframes      INTEGER NOT NULL,
    template_length  INTEGER NOT NULL,
    source           VARCHAR NOT NULL,     -- manual, heuristic, ga
    fitness          DOUBLE,
    precision        DOUBLE,
    recall           DOUBLE,
    PRIMARY KEY (model, class)
);

CREATE TABLE IF NOT EXISTS keyframes (
    model        VARCHAR NOT NULL,
    class        VARCHAR NOT NULL,
    k            INTEGER NOT NULL,         -- 1-based keyframe number
    feature_set  VARCHAR,                  -- upper, lower, mix or NULL (all 40 bits)
    mask         UBIGINT NOT NULL,         -- over the 40-bit word
    value        UBIGINT NOT NULL,
    position     INTEGER NOT NULL,         -- template column (1-based)
    d_min        INTEGER,                  -- bounds on the gap to keyframe k+1 (30 Hz frames);
    d_max        INTEGER,                  -- NULL d_max = unbounded; both NULL for the last
    PRIMARY KEY (model, class, k)
);

-- Calibrated confidence (beyond the paper): per label (and shortest segment length) a step function
-- from a segment's score — with ℓ = min(n, full_length) / full_length, raw · (1 + length_weight · ℓ) /
-- (1 + length_weight) where length_product, else (raw + length_weight · ℓ) / (1 + length_weight);
-- raw = 1 − Δ̄^τ/τ at its best frame, n its length in 30 Hz frames — to the share of right segments seen
-- at that score on recordings the model was not trained on. A segment takes its label's map with the
-- largest min_length it reaches; step k holds from score `cut` up to the next step's. A label without
-- rows keeps the raw score (the toolbox model has none).
CREATE TABLE IF NOT EXISTS confidence_maps (
    model      VARCHAR NOT NULL,
    label      VARCHAR NOT NULL,
    min_length INTEGER NOT NULL,           -- 30 Hz frames
    k          INTEGER NOT NULL,           -- 1-based step number, cuts ascending
    cut        DOUBLE NOT NULL,
    value      DOUBLE NOT NULL,            -- the confidence from this cut on, in [0, 1]
    PRIMARY KEY (model, label, min_length, k)
);
-- the length in the score (databases from before it: the raw score alone); the same on every step of a map
ALTER TABLE confidence_maps ADD COLUMN IF NOT EXISTS length_weight DOUBLE DEFAULT 0;
ALTER TABLE confidence_maps ADD COLUMN IF NOT EXISTS full_length INTEGER DEFAULT 90;
-- the length multiplies the match rather than adding to it (databases from before it: added)
ALTER TABLE confidence_maps ADD COLUMN IF NOT EXISTS length_product BOOLEAN DEFAULT false;

-- Per-generation statistics of the GA runs that learned a model's keyframe
-- queries (population averages: paper Fig. 5; `mocapdb report --figure ga`).
CREATE TABLE IF NOT EXISTS ga_statistics (
    model           VARCHAR NOT NULL,
    class           VARCHAR NOT NULL,
    run             INTEGER NOT NULL,
    generation      INTEGER NOT NULL,
    mean_precision  DOUBLE NOT NULL,
    mean_recall     DOUBLE NOT NULL,
    mean_fitness    DOUBLE NOT NULL,
    best_fitness    DOUBLE NOT NULL,
    mean_keyframes  DOUBLE NOT NULL,
    PRIMARY KEY (model, class, run, generation)
);

-- Materialised annotation results (frames 1-based, inclusive, 30 Hz).
CREATE TABLE IF NOT EXISTS annotations (
    motion_id    INTEGER NOT NULL,
    model        VARCHAR NOT NULL,
    label        VARCHAR NOT NULL,
    start_frame  INTEGER NOT NULL,
    end_frame    INTEGER NOT NULL,
    cost         DOUBLE NOT NULL,
    start_s      DOUBLE NOT NULL,
    end_s        DOUBLE NOT NULL,
    tau          DOUBLE,
    keyframes    BOOLEAN,
    annotated_at TIMESTAMP NOT NULL DEFAULT current_timestamp,
    confidence   DOUBLE                    -- 0-1: how far below tau the segment's best match lies
);
-- databases from before the confidence (issue 25): NULL for the segments stored then
ALTER TABLE annotations ADD COLUMN IF NOT EXISTS confidence DOUBLE;

-- The log of every ingest and import: one row per file, archive member or folder entry an
-- `ingest` looked at, and per motion an `import-features` read (its source file), with what became
-- of it. Rows of files that were stored commit with their motions; the others are written in
-- transactions of their own, so a failed ingest, which leaves the tables above as they were,
-- still leaves its log (DESIGN.md §6). Rows stay when their motion is deleted: it is a history.
CREATE SEQUENCE IF NOT EXISTS ingest_run_seq START 1;

CREATE TABLE IF NOT EXISTS ingest_log (
    run_id     BIGINT NOT NULL,             -- one ingest or import call (ingest_run_seq)
    command    VARCHAR NOT NULL,            -- 'ingest' or 'import-features'
    path       VARCHAR NOT NULL,            -- absolute path of the file (of the archive, for a member)
    member     VARCHAR,                     -- the member inside a zip archive, else NULL
    outcome    VARCHAR NOT NULL CHECK (outcome IN ('ingested', 'skipped', 'failed', 'not a motion file')),
    reason     VARCHAR,                     -- why skipped, failed or not a motion; what an ingested file replaced
    notes      VARCHAR,                     -- what the reader decided, one note a line (motions.reader_options)
    motion_id  BIGINT,                      -- the stored motion; NULL unless ingested
    logged_at  TIMESTAMP NOT NULL DEFAULT current_timestamp
);
