//! Validation of a parsed scene: every value within its range
//! (`limits.rs`), every object and point it names present, the contacts
//! consistent. The first problem found is returned, naming its field.

use super::error::{
    check_abs_max, check_finite, check_max, check_min, check_non_negative, check_positive,
};
use super::limits::{
    MAX_CONTACTS, MAX_DAMPING_N_S_PER_M, MAX_DURATION_S, MAX_FREQ_HZ, MAX_GAIN,
    MAX_GRAVITY_M_PER_S2, MAX_HEIGHT_M, MAX_LEVEL_DB, MAX_LISTENER_DISTANCE_M, MAX_MASS_KG,
    MAX_MODES_PER_OBJECT, MAX_RAYLEIGH_ALPHA_PER_S, MAX_RAYLEIGH_BETA_S, MAX_SPEED_M_PER_S,
    MAX_SPRINGS, MAX_STIFFNESS_N_PER_M, MAX_STRING_MASSES, MAX_WEIGHT, MIN_FREQ_HZ, MIN_LEVEL_DB,
    MIN_LISTENER_DISTANCE_M, MIN_MASS_KG, MIN_STIFFNESS_N_PER_M, MIN_T60_S, SCENE_VERSION,
};
use super::{
    ApproxSpec, End, HammerSpec, ModalSpec, ObjectSpec, PlaySpec, Quantity, Scene, SceneError,
    StrikerSpec, StringSpec, TouchSpec, HAMMER_SIDE,
};

impl Scene {
    /// Check every value; the first problem found is returned.
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.version != SCENE_VERSION {
            return Err(SceneError::new(
                "version",
                format!("must be {SCENE_VERSION}, got {}", self.version),
            ));
        }
        check_positive("duration_s", self.duration_s)?;
        check_max("duration_s", self.duration_s, MAX_DURATION_S)?;
        check_finite("level_db", self.level_db)?;
        if !(MIN_LEVEL_DB..=MAX_LEVEL_DB).contains(&self.level_db) {
            return Err(SceneError::new(
                "level_db",
                format!(
                    "must be within {MIN_LEVEL_DB} ..= {MAX_LEVEL_DB} dB, got {}",
                    self.level_db
                ),
            ));
        }
        if self.object.is_empty() {
            return Err(SceneError::new("object", "at least one object is needed"));
        }
        self.validate_objects()?;
        if let Some(a) = &self.approximate {
            a.validate()?;
        }
        self.hammer.validate()?;
        self.validate_contact()?;
        self.validate_mallet()?;
        self.validate_strikers()?;
        self.validate_touches()?;
        self.validate_law_total()?;
        self.validate_notes()?;
        self.validate_listeners()?;
        self.validate_pickups()?;
        if let Some(p) = &self.play {
            p.validate()?;
        }
        self.validate_drive()?;
        Ok(())
    }

    /// `[drive]`: its values, and a scene it can drive: one contact, a
    /// point-mass hammer.
    fn validate_drive(&self) -> Result<(), SceneError> {
        let Some(d) = &self.drive else {
            return Ok(());
        };
        d.validate()?;
        if self.several_contacts() {
            return Err(SceneError::new(
                "drive",
                "drives the contact of a scene of one contact; this scene has several \
                 ([[striker]], [[touch]] or a contact law of several pieces)",
            ));
        }
        if self.hammer.object.is_some() {
            return Err(SceneError::new(
                "drive",
                "drives a point-mass hammer; hammer.object makes it a modal mallet",
            ));
        }
        Ok(())
    }

    /// Notes: MIDI notes (0..=127), and only where there are several
    /// contacts (they choose among the mallets the instrument strikes).
    fn validate_notes(&self) -> Result<(), SceneError> {
        let lists = std::iter::once(("hammer.notes".to_string(), &self.hammer.notes)).chain(
            self.striker
                .iter()
                .enumerate()
                .map(|(i, st)| (format!("striker[{i}].notes"), &st.notes)),
        );
        for (field, notes) in lists {
            if let Some(&n) = notes.iter().find(|&&n| n > 127) {
                return Err(SceneError::new(
                    field,
                    format!("{n} is not a MIDI note (0 ..= 127)"),
                ));
            }
            if !notes.is_empty() && !self.several_contacts() {
                return Err(SceneError::new(
                    field,
                    "notes choose among the mallets of a scene of several contacts ([[striker]] \
                     or [[touch]]); with one contact every note strikes the hammer: remove it",
                ));
            }
        }
        Ok(())
    }

    /// `[contact] law`: instead of `stiffness_n_per_m`, pieces that are a
    /// law (src/scene/law.rs), one spring each within `MAX_SPRINGS` with
    /// the strikers and touches (and their laws' pieces); with a modal
    /// mallet, on an object of modes or a wall.
    fn validate_law(&self) -> Result<(), SceneError> {
        let c = &self.contact;
        let Some(law) = &c.law else {
            return Ok(());
        };
        if c.stiffness_n_per_m != 0.0 {
            return Err(SceneError::new(
                "contact.stiffness_n_per_m",
                "give either the stiffness or a law: remove one",
            ));
        }
        law.pieces("contact.law")?;
        // a modal mallet's modes join the struck object's before the law
        // is expanded (`Scene::expanded`), so each piece presses on the
        // joined contact point; a lumped string is joined to its mallet
        // later, in the compiler, which the pieces would miss
        let struck_string = self
            .object_index(&c.object)
            .is_some_and(|i| matches!(self.object[i], ObjectSpec::String(_)));
        if self.hammer.object.is_some() && struck_string {
            return Err(SceneError::new(
                "contact.law",
                "not with a modal mallet on a lumped string: a point-mass hammer there",
            ));
        }
        Ok(())
    }

    /// Every contact's law's pieces, one spring each, with the strikers
    /// and touches at most `MAX_SPRINGS` (run after each contact's own
    /// checks).
    fn validate_law_total(&self) -> Result<(), SceneError> {
        let total = self.all_contacts();
        if total <= MAX_SPRINGS {
            return Ok(());
        }
        let field = if self.contact.law.is_some() {
            "contact.law".to_string()
        } else if let Some(i) = self.striker.iter().position(|st| st.law.is_some()) {
            format!("striker[{i}].law")
        } else if let Some(i) = self.touch.iter().position(|t| t.law.is_some()) {
            format!("touch[{i}].law")
        } else {
            "touch".to_string()
        };
        Err(SceneError::new(
            field,
            format!(
                "[contact], {} strikers and {} touches make {total} springs with their laws' \
                 pieces (one spring each), at most {MAX_SPRINGS}",
                self.striker.len(),
                self.touch.len()
            ),
        ))
    }

    /// A striker's or a touch's `law` at `base` (`striker[i]`,
    /// `touch[i]`): its pieces valid and no stiffness beside it; whether
    /// it has one.
    fn validate_own_law(
        base: &str,
        law: Option<&crate::scene::LawSpec>,
        stiffness: f64,
    ) -> Result<bool, SceneError> {
        let Some(law) = law else {
            return Ok(false);
        };
        if stiffness != 0.0 {
            return Err(SceneError::new(
                format!("{base}.stiffness_n_per_m"),
                "give either the stiffness or a law: remove one",
            ));
        }
        law.pieces(&format!("{base}.law"))?;
        Ok(true)
    }

    /// Strikers: at most `MAX_CONTACTS - 1`; each hits a point of the
    /// struck object that no other contact hits, with the values of a
    /// hammer and a contact, and a mallet of its own if it names one;
    /// strikers need an object with points (not a wall).
    fn validate_strikers(&self) -> Result<(), SceneError> {
        if self.striker.is_empty() {
            return Ok(());
        }
        if self.striker.len() >= MAX_CONTACTS {
            return Err(SceneError::new(
                "striker",
                format!(
                    "{} strikers and [contact] make {} contacts, at most {MAX_CONTACTS}",
                    self.striker.len(),
                    self.striker.len() + 1
                ),
            ));
        }
        let obj = self
            .object_index(&self.contact.object)
            .map(|i| &self.object[i])
            .expect("validate_contact ran first");
        if matches!(obj, ObjectSpec::Wall(_)) {
            return Err(SceneError::new(
                "striker",
                "several contacts strike an object with points, not a wall",
            ));
        }
        let names = obj.point_names();
        for (i, st) in self.striker.iter().enumerate() {
            self.validate_striker(i, st, &names)?;
        }
        Ok(())
    }

    /// Striker `i`: its point is one of the struck object's `names` that
    /// no other contact hits, its values those of a hammer and a contact,
    /// and its mallet, if it names one, valid.
    fn validate_striker(
        &self,
        i: usize,
        st: &StrikerSpec,
        names: &[String],
    ) -> Result<(), SceneError> {
        let base = format!("striker[{i}]");
        let f = |k: &str| format!("{base}.{k}");
        if !names.contains(&st.point) {
            return Err(SceneError::new(
                f("point"),
                format!(
                    "object {:?} has no point {:?}",
                    self.contact.object, st.point
                ),
            ));
        }
        let taken = self.contact.point.as_ref() == Some(&st.point)
            || self.striker[..i].iter().any(|o| o.point == st.point);
        if taken {
            return Err(SceneError::new(
                f("point"),
                format!(
                    "another contact already hits {:?}: two contacts on one point pair",
                    st.point
                ),
            ));
        }
        check_positive(&f("mass_kg"), st.mass_kg)?;
        check_min(&f("mass_kg"), st.mass_kg, MIN_MASS_KG)?;
        check_max(&f("mass_kg"), st.mass_kg, MAX_MASS_KG)?;
        check_non_negative(&f("height_m"), st.height_m)?;
        check_max(&f("height_m"), st.height_m, MAX_HEIGHT_M)?;
        check_finite(&f("velocity_m_per_s"), st.velocity_m_per_s)?;
        check_abs_max(
            &f("velocity_m_per_s"),
            st.velocity_m_per_s,
            MAX_SPEED_M_PER_S,
        )?;
        // a law's pieces press on the striker's struck point, less its
        // modal mallet's face where it has one (`MultiModel`'s touches)
        if !Self::validate_own_law(&base, st.law.as_ref(), st.stiffness_n_per_m)? {
            check_stiffness(&f("stiffness_n_per_m"), st.stiffness_n_per_m)?;
        }
        check_non_negative(&f("damping_n_s_per_m"), st.damping_n_s_per_m)?;
        check_max(
            &f("damping_n_s_per_m"),
            st.damping_n_s_per_m,
            MAX_DAMPING_N_S_PER_M,
        )?;
        if let Some(m) = &st.mallet {
            self.validate_striker_mallet(i, st, m)?;
        }
        Ok(())
    }

    /// Striker `i`'s mallet `m`: an object of its own (no other mallet, no
    /// touch names it) and a valid modal mallet.
    fn validate_striker_mallet(
        &self,
        i: usize,
        st: &StrikerSpec,
        m: &End,
    ) -> Result<(), SceneError> {
        let base = format!("striker[{i}]");
        let f = |k: &str| format!("{base}.{k}");
        let used = self.hammer.object.as_ref() == Some(&m.object)
            || self.striker[..i]
                .iter()
                .any(|o| o.mallet.as_ref().is_some_and(|x| x.object == m.object));
        if used {
            return Err(SceneError::new(
                f("mallet.object"),
                format!(
                    "{:?} is another mallet already: each mallet is an object of its own",
                    m.object
                ),
            ));
        }
        let touched = self
            .touch
            .iter()
            .any(|t| t.lower.object == m.object || t.upper.object == m.object);
        if touched {
            return Err(SceneError::new(
                f("mallet.object"),
                format!(
                    "a touch names {:?}: a striker's mallet is struck only through its striker",
                    m.object
                ),
            ));
        }
        self.check_mallet(
            [&f("mallet.object"), &f("mallet.point"), &f("mass_kg")],
            &m.object,
            m.point.as_ref(),
            st.mass_kg,
        )?;
        Ok(())
    }

    /// Touches: at most `MAX_CONTACTS` contacts in all; each side names
    /// the hammer, a wall or an object's point, the two sides differ, no
    /// two contacts join the same pair, values in their ranges.
    fn validate_touches(&self) -> Result<(), SceneError> {
        if self.touch.is_empty() {
            return Ok(());
        }
        let total = 1 + self.striker.len() + self.touch.len();
        if total > MAX_CONTACTS {
            return Err(SceneError::new(
                "touch",
                format!(
                    "[contact], {} strikers and {} touches make {total} contacts, at most \
                     {MAX_CONTACTS}",
                    self.striker.len(),
                    self.touch.len()
                ),
            ));
        }
        // every contact's pair of sides, as (object, point) both ways
        let side_key = |e: &End| (e.object.clone(), e.point.clone());
        let mut pairs = vec![(
            (self.contact.object.clone(), self.contact.point.clone()),
            (HAMMER_SIDE.to_string(), None),
        )];
        for st in &self.striker {
            pairs.push((
                (self.contact.object.clone(), Some(st.point.clone())),
                (HAMMER_SIDE.to_string(), None),
            ));
        }
        for (i, t) in self.touch.iter().enumerate() {
            let f = |k: &str| format!("touch[{i}].{k}");
            let mut walls = 0;
            for (name, e) in [("lower", &t.lower), ("upper", &t.upper)] {
                if e.object == HAMMER_SIDE {
                    self.validate_touch_hammer(i, name, e)?;
                    continue;
                }
                if self.validate_touch_object(i, name, e)? {
                    walls += 1;
                }
            }
            if walls == 2 {
                return Err(SceneError::new(f("upper"), "two walls cannot touch"));
            }
            if t.lower.object == t.upper.object {
                return Err(SceneError::new(
                    f("upper.object"),
                    format!("{:?} in contact with itself", t.lower.object),
                ));
            }
            let (a, b) = (side_key(&t.lower), side_key(&t.upper));
            if pairs
                .iter()
                .any(|(x, y)| (*x == a && *y == b) || (*x == b && *y == a))
            {
                return Err(SceneError::new(
                    f("upper"),
                    "another contact already joins these two sides: two contacts on one point pair",
                ));
            }
            pairs.push((a, b));
            self.validate_touch_values(i, t)?;
        }
        Ok(())
    }

    /// Side `name` of touch `i` is the hammer: no object is also called
    /// `"hammer"`, and a point named is one of the hammer's modal mallet
    /// (its face when none is named).
    fn validate_touch_hammer(&self, i: usize, name: &str, e: &End) -> Result<(), SceneError> {
        let f = |k: &str| format!("touch[{i}].{k}");
        if self.object_index(HAMMER_SIDE).is_some() {
            return Err(SceneError::new(
                f(&format!("{name}.object")),
                "\"hammer\" names both an object and the hammer: rename the object",
            ));
        }
        // a point of the hammer's modal mallet (its face when
        // none is named)
        if let Some(p) = &e.point {
            let Some(m) = &self.hammer.object else {
                return Err(SceneError::new(
                    f(&format!("{name}.point")),
                    "a point-mass hammer has no points; omit the key",
                ));
            };
            let points = self
                .object_index(m)
                .map(|o| self.object[o].point_names())
                .unwrap_or_default();
            if !points.contains(p) {
                return Err(SceneError::new(
                    f(&format!("{name}.point")),
                    format!("the hammer's mallet {m:?} has no point {p:?}: one of {points:?}"),
                ));
            }
        }
        Ok(())
    }

    /// Side `name` of touch `i` is an object: one of the scene's, not the
    /// modal mallet, a wall without a point or an object with modes at one
    /// of its points. Whether it is a wall.
    fn validate_touch_object(&self, i: usize, name: &str, e: &End) -> Result<bool, SceneError> {
        let f = |k: &str| format!("touch[{i}].{k}");
        let Some(o) = self.object_index(&e.object) else {
            return Err(SceneError::new(
                f(&format!("{name}.object")),
                format!("no object named {:?}", e.object),
            ));
        };
        if self.hammer.object.as_ref() == Some(&e.object) {
            return Err(SceneError::new(
                f(&format!("{name}.object")),
                format!(
                    "{:?} is the modal mallet: its face (hammer.point) is the side \
                     \"hammer\"",
                    e.object
                ),
            ));
        }
        let obj = &self.object[o];
        match (obj, &e.point) {
            (ObjectSpec::Wall(_), None) => return Ok(true),
            (ObjectSpec::Wall(_), Some(_)) => {
                return Err(SceneError::new(
                    f(&format!("{name}.point")),
                    "a wall has no points; omit the key",
                ))
            }
            (ObjectSpec::String(_) | ObjectSpec::Chain(_), _) => {
                return Err(SceneError::new(
                    f(&format!("{name}.object")),
                    format!(
                        "{:?} is a lumped {}: several contacts touch objects with modes \
                         (kind \"modal\" or one from geometry and material) and walls",
                        e.object,
                        obj.kind()
                    ),
                ))
            }
            (_, None) => {
                return Err(SceneError::new(
                    f(&format!("{name}.point")),
                    format!(
                        "missing: name one of {:?}'s points {:?}",
                        e.object,
                        obj.point_names()
                    ),
                ))
            }
            (_, Some(p)) if !obj.point_names().contains(p) => {
                return Err(SceneError::new(
                    f(&format!("{name}.point")),
                    format!("object {:?} has no point {p:?}", e.object),
                ))
            }
            _ => {}
        }
        Ok(false)
    }

    /// Touch `i`'s gap, stiffness and damping in their ranges, and the
    /// hammer not starting inside an upper side that rests on it.
    fn validate_touch_values(&self, i: usize, t: &TouchSpec) -> Result<(), SceneError> {
        let f = |k: &str| format!("touch[{i}].{k}");
        check_non_negative(&f("gap_m"), t.gap_m)?;
        check_max(&f("gap_m"), t.gap_m, MAX_HEIGHT_M)?;
        if !Self::validate_own_law(&format!("touch[{i}]"), t.law.as_ref(), t.stiffness_n_per_m)? {
            check_stiffness(&f("stiffness_n_per_m"), t.stiffness_n_per_m)?;
        }
        check_non_negative(&f("damping_n_s_per_m"), t.damping_n_s_per_m)?;
        check_max(
            &f("damping_n_s_per_m"),
            t.damping_n_s_per_m,
            MAX_DAMPING_N_S_PER_M,
        )?;
        // the hammer starts at its height: below an upper side resting
        // `gap` above the struck object's rest, it must not start inside
        let hammer_side = |e: &End| e.object == HAMMER_SIDE;
        if hammer_side(&t.lower) && self.hammer.height_m > t.gap_m {
            return Err(SceneError::new(
                f("gap_m"),
                format!(
                    "the hammer starts at {} m, inside {:?} resting {} m up: raise gap_m or \
                     lower hammer.height_m",
                    self.hammer.height_m, t.upper.object, t.gap_m
                ),
            ));
        }
        Ok(())
    }

    /// Names unique and non-empty, each object's own values.
    fn validate_objects(&self) -> Result<(), SceneError> {
        for (i, obj) in self.object.iter().enumerate() {
            let base = format!("object[{i}]");
            if obj.name().is_empty() {
                return Err(SceneError::new(format!("{base}.name"), "must not be empty"));
            }
            if self.object[..i].iter().any(|o| o.name() == obj.name()) {
                return Err(SceneError::new(
                    format!("{base}.name"),
                    format!("duplicate object name {:?}", obj.name()),
                ));
            }
            match obj {
                ObjectSpec::Modal(m) => validate_modal(&base, m)?,
                ObjectSpec::String(s) => validate_string(&base, s)?,
                ObjectSpec::Wall(_) => {}
                ObjectSpec::Chain(c) => c.validate(&base)?,
                _ => {
                    if let Some(p) = obj.physical() {
                        p.validate(&base)?;
                    }
                }
            }
        }
        Ok(())
    }

    /// The struck object and point exist (a wall has none), and the
    /// spring-damper's values.
    fn validate_contact(&self) -> Result<(), SceneError> {
        let c = &self.contact;
        let Some(obj_idx) = self.object_index(&c.object) else {
            return Err(SceneError::new(
                "contact.object",
                format!("no object named {:?}", c.object),
            ));
        };
        match (&self.object[obj_idx], &c.point) {
            (ObjectSpec::Wall(_), Some(_)) => {
                return Err(SceneError::new(
                    "contact.point",
                    "a wall has no points; omit the key",
                ))
            }
            (ObjectSpec::Wall(_), None) => {}
            (obj, None) => {
                return Err(SceneError::new(
                    "contact.point",
                    format!(
                        "missing: object {:?} is not a wall, name one of its points {:?}",
                        c.object,
                        obj.point_names()
                    ),
                ))
            }
            (obj, Some(p)) => {
                if !obj.point_names().contains(p) {
                    return Err(SceneError::new(
                        "contact.point",
                        format!("object {:?} has no point {:?}", c.object, p),
                    ));
                }
            }
        }
        if c.law.is_some() {
            self.validate_law()?;
        } else {
            if c.stiffness_n_per_m == 0.0 {
                return Err(SceneError::new(
                    "contact.stiffness_n_per_m",
                    "must be > 0, got 0 (missing: give the contact's stiffness, or a law of \
                     several pieces)",
                ));
            }
            check_positive("contact.stiffness_n_per_m", c.stiffness_n_per_m)?;
            check_min(
                "contact.stiffness_n_per_m",
                c.stiffness_n_per_m,
                MIN_STIFFNESS_N_PER_M,
            )?;
            check_max(
                "contact.stiffness_n_per_m",
                c.stiffness_n_per_m,
                MAX_STIFFNESS_N_PER_M,
            )?;
        }
        check_non_negative("contact.damping_n_s_per_m", c.damping_n_s_per_m)?;
        check_max(
            "contact.damping_n_s_per_m",
            c.damping_n_s_per_m,
            MAX_DAMPING_N_S_PER_M,
        )?;
        Ok(())
    }

    /// The listeners: unique names, distance and angles in range.
    fn validate_listeners(&self) -> Result<(), SceneError> {
        for (i, l) in self.listener.iter().enumerate() {
            let base = format!("listener[{i}]");
            if l.name.is_empty() || self.listener[..i].iter().any(|o| o.name == l.name) {
                return Err(SceneError::new(
                    format!("{base}.name"),
                    format!("must be a name no other listener has, got {:?}", l.name),
                ));
            }
            let d = format!("{base}.distance_m");
            check_positive(&d, l.distance_m)?;
            check_min(&d, l.distance_m, MIN_LISTENER_DISTANCE_M)?;
            check_max(&d, l.distance_m, MAX_LISTENER_DISTANCE_M)?;
            let p = format!("{base}.polar_deg");
            check_finite(&p, l.polar_deg)?;
            if !(0.0..=90.0).contains(&l.polar_deg) {
                return Err(SceneError::new(
                    p,
                    format!("must be within 0 ..= 90, got {}", l.polar_deg),
                ));
            }
            let a = format!("{base}.azimuth_deg");
            check_finite(&a, l.azimuth_deg)?;
            check_abs_max(&a, l.azimuth_deg, 360.0)?;
        }
        Ok(())
    }

    /// Each pickup's object and point exist; gain and pan.
    fn validate_pickups(&self) -> Result<(), SceneError> {
        for (i, p) in self.pickup.iter().enumerate() {
            let base = format!("pickup[{i}]");
            let Some(oi) = self.object_index(&p.object) else {
                return Err(SceneError::new(
                    format!("{base}.object"),
                    format!("no object named {:?}", p.object),
                ));
            };
            if p.quantity == Quantity::Pressure {
                if self.object[oi].physical().is_none() {
                    return Err(SceneError::new(
                        format!("{base}.quantity"),
                        format!(
                            "pressure needs an object from geometry (bar, tube, plate, membrane, \
                             stiff_string); {:?} is a {}",
                            p.object,
                            self.object[oi].kind()
                        ),
                    ));
                }
                if !self.listener.iter().any(|l| l.name == p.point) {
                    return Err(SceneError::new(
                        format!("{base}.point"),
                        format!(
                            "a pressure pickup names a listener: no [[listener]] {:?}",
                            p.point
                        ),
                    ));
                }
            } else if !self.object[oi].point_names().contains(&p.point) {
                return Err(SceneError::new(
                    format!("{base}.point"),
                    format!("object {:?} has no point {:?}", p.object, p.point),
                ));
            }
            check_finite(&format!("{base}.gain"), p.gain)?;
            check_abs_max(&format!("{base}.gain"), p.gain, MAX_GAIN)?;
            // the gain the engine gets: times the scene's level
            let heard = p.gain * self.level_gain();
            if heard.abs() > MAX_GAIN {
                return Err(SceneError::new(
                    "level_db",
                    format!(
                        "{base}.gain {:e} at level_db {} makes {heard:e}; |gain x level| must be <= {MAX_GAIN:e}",
                        p.gain, self.level_db
                    ),
                ));
            }
            check_finite(&format!("{base}.pan"), p.pan)?;
            if !(-1.0..=1.0).contains(&p.pan) {
                return Err(SceneError::new(
                    format!("{base}.pan"),
                    format!("must be in [-1, 1], got {}", p.pan),
                ));
            }
        }
        Ok(())
    }
}

impl ApproxSpec {
    fn validate(&self) -> Result<(), SceneError> {
        if let Some(f) = self.max_freq_hz {
            check_positive("approximate.max_freq_hz", f)?;
        }
        if let Some(f) = self.nyquist_fraction {
            check_positive("approximate.nyquist_fraction", f)?;
        }
        if let Some(db) = self.quiet_below_db {
            check_finite("approximate.quiet_below_db", db)?;
            if db >= 0.0 {
                return Err(SceneError::new(
                    "approximate.quiet_below_db",
                    format!("must be < 0 dB, got {db}"),
                ));
            }
        }
        Ok(())
    }
}

impl PlaySpec {
    fn validate(&self) -> Result<(), SceneError> {
        if let Some(d) = self.damper {
            check_finite("play.damper", d)?;
            if !(0.0..=1.0).contains(&d) {
                return Err(SceneError::new(
                    "play.damper",
                    format!("must be within 0 ..= 1, got {d}"),
                ));
            }
        }
        if let Some(f) = self.pitch_hz {
            check_positive("play.pitch_hz", f)?;
            // MIDI notes 0 ..= 127 (8.2 Hz ..= 12.5 kHz)
            check_min("play.pitch_hz", f, 8.0)?;
            check_max("play.pitch_hz", f, 13_000.0)?;
        }
        Ok(())
    }
}

impl HammerSpec {
    fn validate(&self) -> Result<(), SceneError> {
        let h = self;
        check_positive("hammer.mass_kg", h.mass_kg)?;
        check_min("hammer.mass_kg", h.mass_kg, MIN_MASS_KG)?;
        check_max("hammer.mass_kg", h.mass_kg, MAX_MASS_KG)?;
        check_non_negative("hammer.height_m", h.height_m)?;
        check_max("hammer.height_m", h.height_m, MAX_HEIGHT_M)?;
        check_finite("hammer.velocity_m_per_s", h.velocity_m_per_s)?;
        check_abs_max(
            "hammer.velocity_m_per_s",
            h.velocity_m_per_s,
            MAX_SPEED_M_PER_S,
        )?;
        check_non_negative("hammer.gravity_m_per_s2", h.gravity_m_per_s2)?;
        check_max(
            "hammer.gravity_m_per_s2",
            h.gravity_m_per_s2,
            MAX_GRAVITY_M_PER_S2,
        )?;

        Ok(())
    }
}

fn validate_modal(base: &str, m: &ModalSpec) -> Result<(), SceneError> {
    if m.mode.is_empty() {
        return Err(SceneError::new(
            format!("{base}.mode"),
            "a modal object needs at least one mode",
        ));
    }
    if m.mode.len() > MAX_MODES_PER_OBJECT {
        return Err(SceneError::new(
            format!("{base}.mode"),
            format!(
                "{} modes is more than the limit of {MAX_MODES_PER_OBJECT}",
                m.mode.len()
            ),
        ));
    }
    for (j, p) in m.points.iter().enumerate() {
        if p.is_empty() {
            return Err(SceneError::new(
                format!("{base}.points[{j}]"),
                "must not be empty",
            ));
        }
        if m.points[..j].contains(p) {
            return Err(SceneError::new(
                format!("{base}.points[{j}]"),
                format!("duplicate point name {p:?}"),
            ));
        }
    }
    for (k, mode) in m.mode.iter().enumerate() {
        let mb = format!("{base}.mode[{k}]");
        check_positive(&format!("{mb}.freq_hz"), mode.freq_hz)?;
        if mode.freq_hz > MAX_FREQ_HZ {
            return Err(SceneError::new(
                format!("{mb}.freq_hz"),
                format!("must be <= {MAX_FREQ_HZ}, got {}", mode.freq_hz),
            ));
        }
        check_min(&format!("{mb}.freq_hz"), mode.freq_hz, MIN_FREQ_HZ)?;
        if let Some(t60) = mode.t60_s {
            check_positive(&format!("{mb}.t60_s"), t60)?;
            check_min(&format!("{mb}.t60_s"), t60, MIN_T60_S)?;
        }
        if mode.weights.len() != m.points.len() {
            return Err(SceneError::new(
                format!("{mb}.weights"),
                format!(
                    "needs one weight per point ({}), got {}",
                    m.points.len(),
                    mode.weights.len()
                ),
            ));
        }
        for (j, w) in mode.weights.iter().enumerate() {
            check_finite(&format!("{mb}.weights[{j}]"), *w)?;
            if w.abs() > MAX_WEIGHT {
                return Err(SceneError::new(
                    format!("{mb}.weights[{j}]"),
                    format!(
                        "|w| must be <= {MAX_WEIGHT:e} 1/sqrt(kg) (an effective mass >= {MIN_MASS_KG:e} kg), got {w}"
                    ),
                ));
            }
        }
    }
    Ok(())
}

fn validate_string(base: &str, s: &StringSpec) -> Result<(), SceneError> {
    if s.masses == 0 || s.masses > MAX_STRING_MASSES {
        return Err(SceneError::new(
            format!("{base}.masses"),
            format!("must be in 1..={MAX_STRING_MASSES}, got {}", s.masses),
        ));
    }
    check_positive(&format!("{base}.mass_kg"), s.mass_kg)?;
    check_min(&format!("{base}.mass_kg"), s.mass_kg, MIN_MASS_KG)?;
    check_max(&format!("{base}.mass_kg"), s.mass_kg, MAX_MASS_KG)?;
    check_positive(&format!("{base}.spring_n_per_m"), s.spring_n_per_m)?;
    check_max(
        &format!("{base}.spring_n_per_m"),
        s.spring_n_per_m,
        MAX_STIFFNESS_N_PER_M,
    )?;
    // The chain's modes must lie in the same frequency range as a modal
    // object's modes.
    let f_lo = s.mode_freq_hz(1);
    let f_hi = s.mode_freq_hz(s.masses);
    if f_hi > MAX_FREQ_HZ {
        return Err(SceneError::new(
            format!("{base}.spring_n_per_m"),
            format!(
                "with mass_kg = {:e} the highest mode is at {f_hi:.3e} Hz, above {MAX_FREQ_HZ:e} Hz (spring too stiff or masses too light)",
                s.mass_kg
            ),
        ));
    }
    if f_lo < MIN_FREQ_HZ {
        return Err(SceneError::new(
            format!("{base}.spring_n_per_m"),
            format!(
                "with mass_kg = {:e} the lowest mode is at {f_lo:.3e} Hz, below {MIN_FREQ_HZ:e} Hz (spring too soft or masses too heavy)",
                s.mass_kg
            ),
        ));
    }
    check_non_negative(
        &format!("{base}.rayleigh_alpha_per_s"),
        s.rayleigh_alpha_per_s,
    )?;
    check_max(
        &format!("{base}.rayleigh_alpha_per_s"),
        s.rayleigh_alpha_per_s,
        MAX_RAYLEIGH_ALPHA_PER_S,
    )?;
    check_non_negative(&format!("{base}.rayleigh_beta_s"), s.rayleigh_beta_s)?;
    check_max(
        &format!("{base}.rayleigh_beta_s"),
        s.rayleigh_beta_s,
        MAX_RAYLEIGH_BETA_S,
    )?;
    for (j, d) in s.dashpots.iter().enumerate() {
        if d.mass >= s.masses {
            return Err(SceneError::new(
                format!("{base}.dashpots[{j}].mass"),
                format!("must be < masses ({}), got {}", s.masses, d.mass),
            ));
        }
        check_non_negative(&format!("{base}.dashpots[{j}].n_s_per_m"), d.n_s_per_m)?;
        check_max(
            &format!("{base}.dashpots[{j}].n_s_per_m"),
            d.n_s_per_m,
            MAX_DAMPING_N_S_PER_M,
        )?;
    }
    for (name, &idx) in &s.points {
        if idx >= s.masses {
            return Err(SceneError::new(
                format!("{base}.points.{name}"),
                format!("must be < masses ({}), got {idx}", s.masses),
            ));
        }
    }
    Ok(())
}

/// A contact's stiffness at `field`: positive and within the scene's
/// limits (0, missing, says a law may take its place).
fn check_stiffness(field: &str, k: f64) -> Result<(), SceneError> {
    if k == 0.0 {
        return Err(SceneError::new(
            field,
            "must be > 0, got 0 (missing: give the contact's stiffness, or a law of several \
             pieces)",
        ));
    }
    check_positive(field, k)?;
    check_min(field, k, MIN_STIFFNESS_N_PER_M)?;
    check_max(field, k, MAX_STIFFNESS_N_PER_M)
}
