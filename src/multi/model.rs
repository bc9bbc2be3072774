//! The several-contact model: its checks ([`MultiModel::validate`]), the
//! compile budget, and the model of a scene file ([`MultiModel::from_scene`]).

use super::*;

impl SceneNames {
    pub(super) fn of(scene: &Scene) -> Self {
        let c = &scene.contact;
        let struck = if c.point.is_some() {
            "contact.point"
        } else {
            "contact.object"
        };
        let mut contacts = vec![[
            "contact".to_string(),
            struck.to_string(),
            "hammer".to_string(),
            "hammer.height_m".to_string(),
        ]];
        let mut masses = vec!["hammer".to_string()];
        for i in 0..scene.striker.len() {
            let s = format!("striker[{i}]");
            contacts.push([
                s.clone(),
                format!("{s}.point"),
                s.clone(),
                format!("{s}.height_m"),
            ]);
            masses.push(s);
        }
        for i in 0..scene.touch.len() {
            let t = format!("touch[{i}]");
            contacts.push([
                t.clone(),
                format!("{t}.lower"),
                format!("{t}.upper"),
                format!("{t}.gap_m"),
            ]);
        }
        Self {
            key: if scene.touch.is_empty() {
                "striker"
            } else {
                "touch"
            },
            contacts,
            masses,
            largest: None,
        }
    }

    /// A model's field, as [`MultiModel::validate`] names it, as the
    /// scene's.
    fn field(&self, field: &str) -> String {
        let indexed = |prefix: &str| -> Option<(usize, &str)> {
            let (i, rest) = field.strip_prefix(prefix)?.split_once(']')?;
            Some((i.parse().ok()?, rest))
        };
        if let Some((j, rest)) = indexed("contacts[") {
            if let Some(c) = self.contacts.get(j) {
                if rest.starts_with(".lower") {
                    return c[1].clone();
                }
                if rest.starts_with(".upper") {
                    return c[2].clone();
                }
                return format!("{}{rest}", c[0]);
            }
        }
        if let Some((j, rest)) = indexed("masses[") {
            if let Some(m) = self.masses.get(j) {
                return format!("{m}{rest}");
            }
        }
        match field {
            "gravity_m_per_s2" => "hammer.gravity_m_per_s2".into(),
            f if f.starts_with("freq_hz") || f.starts_with("sigma") => "object".into(),
            f if f.starts_with("pickups") => "pickup".into(),
            f if f.starts_with("masses") => "striker".into(),
            f => f.into(),
        }
    }

    /// `e` as a scene error naming the scene's field.
    pub(super) fn error(&self, e: &MultiError) -> SceneError {
        let name = |j: usize| {
            self.contacts
                .get(j)
                .map_or_else(|| format!("contacts[{j}]"), |c| c[0].clone())
        };
        match e {
            MultiError::ContactCount(n) => SceneError::new(
                self.key,
                format!(
                    "{n} contacts with their laws' pieces, a scene of several contacts has 1 to \
                     {MAX_SPRINGS}"
                ),
            ),
            MultiError::Length { field, got, want } => {
                SceneError::new(self.field(field), format!("{got} entries for {want} modes"))
            }
            MultiError::Value { field, value } => {
                SceneError::new(self.field(field), format!("{value} is out of range"))
            }
            MultiError::SamePoint(a, b) => SceneError::new(
                name(*b),
                format!(
                    "the same pair as {} (the same two sides the same way round at the same \
                     gap; two walls at one height are one surface): two contacts on one point \
                     pair; make them one contact, or set them apart with gap_m",
                    name(*a)
                ),
            ),
            MultiError::Sides { contact, part, why } => {
                let k = match *part {
                    "lower" => 1,
                    "upper" => 2,
                    "gap_m" => 3,
                    _ => 0,
                };
                let path = self
                    .contacts
                    .get(*contact)
                    .map_or_else(|| format!("contacts[{contact}]"), |c| c[k].clone());
                SceneError::new(path, why.clone())
            }
            MultiError::OverBudget {
                phases,
                dim,
                flops,
                bytes,
            } => SceneError::new(
                self.largest.clone().unwrap_or_else(|| "object".into()),
                over_budget(*phases, *dim, *flops, *bytes),
            ),
            MultiError::Phase { mask, why } => {
                let members: Vec<String> = (0..MAX_SPRINGS)
                    .filter(|j| mask & (1 << j) != 0)
                    .map(name)
                    .collect();
                SceneError::new(
                    members.first().cloned().unwrap_or_else(|| self.key.into()),
                    format!("the phase with {} in contact: {why}", members.join(", ")),
                )
            }
        }
    }
}

impl MultiModel {
    pub(super) fn n(&self) -> usize {
        self.freq_hz.len()
    }

    /// One modal object struck by point-mass hammers, each through a
    /// contact of its own at a point of its own (contact `j` is hammer
    /// `j`'s).
    pub fn struck(
        freq_hz: Vec<f64>,
        sigma: Vec<f64>,
        hammers: &[MultiHammer],
        gravity_m_per_s2: f64,
        pickups: [(Vec<f64>, Vec<f64>); 2],
    ) -> Self {
        Self {
            freq_hz,
            sigma,
            masses: hammers
                .iter()
                .map(|h| MultiMass {
                    mass_kg: h.mass_kg,
                    height_m: h.height_m,
                    velocity_m_per_s: h.velocity_m_per_s,
                })
                .collect(),
            contacts: hammers
                .iter()
                .enumerate()
                .map(|(j, h)| MultiContact {
                    lower: MultiEnd::Point(h.weights.clone()),
                    upper: MultiEnd::Mass(j),
                    gap_m: 0.0,
                    stiffness_n_per_m: h.stiffness_n_per_m,
                    damping_n_s_per_m: h.damping_n_s_per_m,
                })
                .collect(),
            gravity_m_per_s2,
            pickups,
        }
    }

    /// A side's initial height (the objects start at rest).
    fn rest_height(&self, e: &MultiEnd) -> f64 {
        match e {
            MultiEnd::Point(_) => 0.0,
            MultiEnd::Mass(j) => self.masses[*j].height_m,
            MultiEnd::Wall(h) => *h,
        }
    }

    /// Check every field (a clear error naming it, never a panic).
    pub fn validate(&self) -> Result<(), MultiError> {
        let k = self.contacts.len();
        if k == 0 || k > MAX_SPRINGS {
            return Err(MultiError::ContactCount(k));
        }
        self.validate_modes_and_pickups()?;
        self.validate_masses()?;
        for (j, c) in self.contacts.iter().enumerate() {
            self.validate_contact(j, c)?;
        }
        Ok(())
    }

    /// `got` entries in `field`, one per mode, or a length error.
    fn check_len(&self, field: &str, got: usize) -> Result<(), MultiError> {
        let n = self.n();
        if got == n {
            Ok(())
        } else {
            Err(MultiError::Length {
                field: field.into(),
                got,
                want: n,
            })
        }
    }

    /// The per-mode lists (frequencies, decay rates, pickup rows) and
    /// gravity.
    fn validate_modes_and_pickups(&self) -> Result<(), MultiError> {
        let n = self.n();
        self.check_len("sigma", self.sigma.len())?;
        for (c, (d, v)) in self.pickups.iter().enumerate() {
            self.check_len(&format!("pickups[{c}].displacement"), d.len())?;
            self.check_len(&format!("pickups[{c}].velocity"), v.len())?;
            for (i, x) in d.iter().chain(v).enumerate() {
                check_value(&format!("pickups[{c}][{i}]"), *x, true)?;
            }
        }
        for i in 0..n {
            check_value(
                &format!("freq_hz[{i}]"),
                self.freq_hz[i],
                self.freq_hz[i] > 0.0,
            )?;
            check_value(&format!("sigma[{i}]"), self.sigma[i], self.sigma[i] >= 0.0)?;
        }
        check_value(
            "gravity_m_per_s2",
            self.gravity_m_per_s2,
            self.gravity_m_per_s2 >= 0.0,
        )
    }

    /// The point masses: how many, and each one's mass, height and
    /// velocity.
    fn validate_masses(&self) -> Result<(), MultiError> {
        // every mass can be in a contact: at most two per contact
        if self.masses.len() > 2 * MAX_CONTACTS {
            return Err(MultiError::Value {
                field: "masses (more than two per contact)".into(),
                value: self.masses.len() as f64,
            });
        }
        for (j, m) in self.masses.iter().enumerate() {
            let f = |name: &str| format!("masses[{j}].{name}");
            check_value(&f("mass_kg"), m.mass_kg, m.mass_kg > 0.0)?;
            check_value(&f("height_m"), m.height_m, true)?;
            check_value(&f("velocity_m_per_s"), m.velocity_m_per_s, true)?;
        }
        Ok(())
    }

    /// Contact `j`: its spring and damper, its two sides, its start apart
    /// or touching, and no earlier contact on the same penetration.
    fn validate_contact(&self, j: usize, c: &MultiContact) -> Result<(), MultiError> {
        let f = |name: &str| format!("contacts[{j}].{name}");
        let sides = |part: &'static str, why: String| MultiError::Sides {
            contact: j,
            part,
            why,
        };
        check_value(
            &f("stiffness_n_per_m"),
            c.stiffness_n_per_m,
            c.stiffness_n_per_m > 0.0,
        )?;
        check_value(
            &f("damping_n_s_per_m"),
            c.damping_n_s_per_m,
            c.damping_n_s_per_m >= 0.0,
        )?;
        check_value(&f("gap_m"), c.gap_m, true)?;
        for (name, e) in [("lower", &c.lower), ("upper", &c.upper)] {
            self.validate_side(j, name, e)?;
        }
        if matches!((&c.lower, &c.upper), (MultiEnd::Wall(_), MultiEnd::Wall(_))) {
            return Err(sides("upper", "two walls cannot touch".into()));
        }
        if c.lower == c.upper {
            return Err(sides("upper", "a side in contact with itself".into()));
        }
        let p0 = self.rest_height(&c.lower) - self.rest_height(&c.upper) - c.gap_m;
        if p0 > 0.0 {
            return Err(sides(
                "gap_m",
                format!("starts {p0:e} m pressed in: its sides must start apart or touching"),
            ));
        }
        if let Some(l) = self.contacts[..j]
            .iter()
            .position(|other| same_penetration(other, c))
        {
            return Err(MultiError::SamePoint(l, j));
        }
        Ok(())
    }

    /// Side `name` (`"lower"` or `"upper"`) of contact `j`: a point's
    /// weights, a mass that exists, or a wall's height.
    fn validate_side(&self, j: usize, name: &'static str, e: &MultiEnd) -> Result<(), MultiError> {
        let f = |field: &str| format!("contacts[{j}].{field}");
        match e {
            MultiEnd::Point(w) => {
                self.check_len(&f(&format!("{name}.weights")), w.len())?;
                for (i, x) in w.iter().enumerate() {
                    check_value(&f(&format!("{name}.weights[{i}]")), *x, true)?;
                }
            }
            MultiEnd::Mass(m) if *m >= self.masses.len() => {
                return Err(MultiError::Sides {
                    contact: j,
                    part: name,
                    why: format!("{name} is mass {m}, there are {}", self.masses.len()),
                });
            }
            MultiEnd::Mass(_) => {}
            MultiEnd::Wall(h) => check_value(&f(&format!("{name}.wall")), *h, true)?,
        }
        Ok(())
    }
}

impl MultiModel {
    /// Each contact's stage below: the contact with the same sides the
    /// same way round at the nearest smaller penetration offset (a law's
    /// previous piece, a touch's nearer stage), `None` for a first stage.
    /// Its penetration is this one's plus the difference of the offsets,
    /// so whenever this contact presses, the one below presses too:
    /// a phase with a contact closed and its stage below open is never
    /// reached (docs/numerics.md section 14, "Phases that are reached").
    pub fn stage_below(&self) -> Vec<Option<usize>> {
        let c = &self.contacts;
        let off = |i: usize| penetration_offset(&c[i]);
        (0..c.len())
            .map(|j| {
                (0..c.len())
                    .filter(|&i| same_sides(&c[i], &c[j]) && off(i) < off(j))
                    .max_by(|&a, &b| off(a).total_cmp(&off(b)))
            })
            .collect()
    }

    /// The phases that can be reached, in increasing order: the masks in
    /// which every closed contact's stage below is closed too
    /// ([`stage_below`](Self::stage_below)). All `2^K` when no two
    /// contacts are stages of one another; `P + 1` for a law of `P`
    /// pieces.
    pub fn reachable_masks(&self) -> Vec<u32> {
        self.reachable_masks_of(&self.stage_below())
    }

    /// [`reachable_masks`](Self::reachable_masks) with the stages below
    /// already found.
    pub(super) fn reachable_masks_of(&self, below: &[Option<usize>]) -> Vec<u32> {
        (0..1u32 << self.contacts.len())
            .filter(|&mask| {
                below
                    .iter()
                    .enumerate()
                    .all(|(j, b)| mask & (1 << j) == 0 || b.is_none_or(|i| mask & (1 << i) != 0))
            })
            .collect()
    }

    /// Every phase's eigendecomposition and checks (about 40 d^3 flop for
    /// d coordinates) and its two bases (2 d^2 numbers) within the compile
    /// budget: refused before any of it.
    pub(super) fn within_budget(&self) -> Result<(), MultiError> {
        self.within_budget_of(self.reachable_masks().len())
    }

    /// [`within_budget`](Self::within_budget) for `phases` phases.
    pub(super) fn within_budget_of(&self, phases: usize) -> Result<(), MultiError> {
        let dim = 2 * (self.n() + self.masses.len());
        let d = dim as f64;
        let flops = phases as f64 * 40.0 * d * d * d;
        let bytes = phases as f64 * 3.0 * d * d * 8.0;
        let budget = CompileBudget::DEFAULT;
        if flops > budget.max_flops || bytes > budget.max_bytes {
            return Err(MultiError::OverBudget {
                phases,
                dim,
                flops,
                bytes,
            });
        }
        Ok(())
    }
}

/// Two contacts with one penetration `p = x_lower - x_upper - gap`: the
/// same sides the same way round, and the same gap once a wall's height is
/// counted in it (`p = h - x_upper - gap` against a wall below, `x_lower -
/// h - gap` against one above), so a wall is told by where it is, not by
/// its kind. Such a pair is one spring-damper twice. The same sides the
/// other way round are two faces (a mass between a floor and a ceiling),
/// at another gap two stages of a contact: different contacts.
fn same_penetration(a: &MultiContact, b: &MultiContact) -> bool {
    same_sides(a, b) && penetration_offset(a) == penetration_offset(b)
}

/// The same sides the same way round (any two walls alike: a wall is told
/// by its height, counted in [`penetration_offset`]).
fn same_sides(a: &MultiContact, b: &MultiContact) -> bool {
    let same = |x: &MultiEnd, y: &MultiEnd| match (x, y) {
        (MultiEnd::Wall(_), MultiEnd::Wall(_)) => true,
        _ => x == y,
    };
    same(&a.lower, &b.lower) && same(&a.upper, &b.upper)
}

/// What a contact subtracts from `x_lower - x_upper` in its penetration,
/// a wall's height counted in (`p = x_lower - x_upper - offset` with a
/// wall's side at 0).
fn penetration_offset(c: &MultiContact) -> f64 {
    let wall = |e: &MultiEnd| match e {
        MultiEnd::Wall(h) => *h,
        _ => 0.0,
    };
    c.gap_m - wall(&c.lower) + wall(&c.upper)
}

/// The scene's objects a side of a contact names, as the model's sides
/// (docs/design.md, "Several contacts").
struct SceneSides<'a> {
    scene: &'a Scene,
    /// Per object: its first mode in the model's list (modal objects in a
    /// contact only).
    first_mode: Vec<Option<usize>>,
    n: usize,
}

impl SceneSides<'_> {
    fn object(&self, field: &str, name: &str) -> Result<usize, SceneError> {
        self.scene
            .object_index(name)
            .ok_or_else(|| SceneError::new(field, format!("no object named {name:?}")))
    }

    /// The weights of object `name`'s point `point` over the model's modes.
    fn point(&self, field: &str, name: &str, point: &str) -> Result<Vec<f64>, SceneError> {
        let o = self.object(field, name)?;
        let ObjectSpec::Modal(m) = &self.scene.object[o] else {
            return Err(SceneError::new(field, format!("{name:?} has no modes")));
        };
        let k = m.points.iter().position(|p| p == point).ok_or_else(|| {
            SceneError::new(field, format!("object {name:?} has no point {point:?}"))
        })?;
        let first = self.first_mode[o].expect("every object in a contact has its modes placed");
        let mut w = vec![0.0; self.n];
        for (i, md) in m.mode.iter().enumerate() {
            w[first + i] = md.weights[k];
        }
        Ok(w)
    }

    /// A touch's side: the hammer (or a striker, where a striker's law
    /// put it), a wall, or a point of an object.
    fn side(&self, field: &str, end: &SceneEnd) -> Result<MultiEnd, SceneError> {
        if end.object == crate::scene::HAMMER_SIDE {
            return Ok(MultiEnd::Mass(end.striker.map_or(0, |i| 1 + i)));
        }
        let o = self.object(field, &end.object)?;
        match (&self.scene.object[o], &end.point) {
            (ObjectSpec::Wall(_), _) => Ok(MultiEnd::Wall(0.0)),
            (_, Some(p)) => Ok(MultiEnd::Point(self.point(field, &end.object, p)?)),
            (_, None) => Err(SceneError::new(
                field,
                format!("{:?} needs a point", end.object),
            )),
        }
    }
}

impl MultiModel {
    /// The model of a scene with strikers or touches (docs/design.md,
    /// "Several contacts"): every modal object in a contact (objects from
    /// geometry and material become their modes at `rate_hz`), mass 0 the
    /// `[hammer]` and mass `1 + i` striker `i`; contact 0 is `[contact]`,
    /// then each `[[striker]]`'s, then each `[[touch]]`; the pickups on
    /// objects in a contact (those elsewhere hear nothing). A clear error
    /// naming the field where the scene asks for what several contacts do
    /// not take yet; the model's own checks and the compile budget are
    /// taken here too, each refusal naming the scene's field
    /// ([`MultiError::in_scene`]).
    pub fn from_scene(scene: &Scene, rate_hz: f64) -> Result<Self, SceneError> {
        scene.validate()?;
        let mut names = SceneNames::of(scene);
        let given = scene;
        let original_mallet = scene.hammer.object.clone().zip(scene.hammer.point.clone());
        let expanded = scene.expanded(rate_hz)?;
        let scene = &expanded;
        if scene.approximate.is_some() {
            return Err(SceneError::new(
                "approximate",
                "not with several contacts yet: remove it",
            ));
        }
        if scene.drive.is_some() {
            return Err(SceneError::new(
                "drive",
                "a driven contact runs on the one-contact engine (crate::compile_one), not with \
                 several contacts",
            ));
        }
        let (first_mode, freq_hz, sigma) = place_modes(scene, given, &mut names)?;
        let n = freq_hz.len();
        let sides = SceneSides {
            scene,
            first_mode,
            n,
        };
        let c = &scene.contact;
        let mut masses = vec![MultiMass {
            mass_kg: scene.hammer.mass_kg,
            height_m: scene.hammer.height_m,
            velocity_m_per_s: scene.hammer.velocity_m_per_s,
        }];
        let mut contacts = vec![MultiContact {
            lower: sides.struck_side()?,
            upper: MultiEnd::Mass(0),
            gap_m: 0.0,
            stiffness_n_per_m: c.stiffness_n_per_m,
            damping_n_s_per_m: c.damping_n_s_per_m,
        }];
        sides.push_strikers(&mut masses, &mut contacts)?;
        sides.push_touches(original_mallet.as_ref(), &mut contacts)?;
        let pickups = sides.pickups()?;
        let model = MultiModel {
            freq_hz,
            sigma,
            masses,
            contacts,
            gravity_m_per_s2: scene.hammer.gravity_m_per_s2,
            pickups,
        };
        model
            .validate()
            .and_then(|()| model.within_budget())
            .map_err(|e| names.error(&e))?;
        Ok(model)
    }
}

/// The objects in a contact, by name, each with the scene field naming it:
/// `[contact]`'s, each striker's modal mallet, each touch's sides other
/// than the hammer.
fn contact_objects(scene: &Scene) -> Vec<(String, &str)> {
    let mut named: Vec<(String, &str)> = vec![("contact.object".into(), &scene.contact.object)];
    for (i, st) in scene.striker.iter().enumerate() {
        if let Some(m) = &st.mallet {
            named.push((format!("striker[{i}].mallet.object"), &m.object));
        }
    }
    for (i, t) in scene.touch.iter().enumerate() {
        for (side, e) in [("lower", &t.lower), ("upper", &t.upper)] {
            if e.object != crate::scene::HAMMER_SIDE {
                named.push((format!("touch[{i}].{side}.object"), &e.object));
            }
        }
    }
    named
}

/// Per object its first mode in the model's list (or `None`), and the
/// modes' frequencies (Hz) and decay rates (1/s).
type PlacedModes = (Vec<Option<usize>>, Vec<f64>, Vec<f64>);

/// The modes of every modal object in a contact, in the order first named
/// (objects of the expanded `scene`). Notes in `names` the given scene's
/// object with the most modes (the one a refused budget names).
fn place_modes(
    scene: &Scene,
    given: &Scene,
    names: &mut SceneNames,
) -> Result<PlacedModes, SceneError> {
    let mut first_mode = vec![None; scene.object.len()];
    let (mut freq_hz, mut sigma) = (vec![], vec![]);
    let mut most = 0;
    for (field, name) in contact_objects(scene) {
        let field = field.as_str();
        let o = scene
            .object_index(name)
            .ok_or_else(|| SceneError::new(field, format!("no object named {name:?}")))?;
        match &scene.object[o] {
            ObjectSpec::Modal(m) => {
                if first_mode[o].is_none() {
                    first_mode[o] = Some(freq_hz.len());
                    for md in &m.mode {
                        freq_hz.push(md.freq_hz);
                        sigma.push(md.t60_s.map_or(0.0, |t| LN_1000 / t));
                    }
                    if m.mode.len() > most {
                        most = m.mode.len();
                        names.largest = given.object_index(name).map(|o| format!("object[{o}]"));
                    }
                }
            }
            ObjectSpec::Wall(_) => {}
            _ => {
                return Err(SceneError::new(
                    field,
                    format!(
                        "several contacts touch objects with modes (kind \"modal\" or one \
                         from geometry and material) and walls, not {:?} (a lumped string)",
                        name
                    ),
                ))
            }
        }
    }
    Ok((first_mode, freq_hz, sigma))
}

/// A touch's side `e` on the hammer, less the hammer's modal mallet face
/// `psi` (if any), with the gap that keeps the penetration the same; `below`
/// when `e` is the lower side.
fn less_face(e: MultiEnd, gap: f64, below: bool, psi: Option<Vec<f64>>) -> (MultiEnd, f64) {
    let Some(psi) = psi else {
        return (e, gap);
    };
    match e {
        MultiEnd::Point(w) => (
            MultiEnd::Point(w.iter().zip(psi).map(|(a, b)| a - b).collect()),
            gap,
        ),
        // p = h - x_h - psi a - gap = (-psi a) - x_h - (gap - h), or
        // p = x_h + psi a - h - gap = x_h - (-psi a) - (gap + h)
        MultiEnd::Wall(h) => (
            MultiEnd::Point(psi.iter().map(|x| -x).collect()),
            if below { gap - h } else { gap + h },
        ),
        MultiEnd::Mass(j) => (MultiEnd::Mass(j), gap),
    }
}

/// Per output channel: the displacement and the velocity pickup rows over
/// the model's modes.
type PickupRows = [(Vec<f64>, Vec<f64>); 2];

impl SceneSides<'_> {
    /// `[contact]`'s lower side: its point of the struck object, or the
    /// object itself (a wall).
    fn struck_side(&self) -> Result<MultiEnd, SceneError> {
        let c = &self.scene.contact;
        match &c.point {
            Some(p) => Ok(MultiEnd::Point(self.point(
                "contact.point",
                &c.object,
                p,
            )?)),
            None => self.side(
                "contact.object",
                &SceneEnd {
                    object: c.object.clone(),
                    point: None,
                    striker: None,
                },
            ),
        }
    }

    /// Each `[[striker]]` as mass `1 + i` and its contact on the struck
    /// object.
    fn push_strikers(
        &self,
        masses: &mut Vec<MultiMass>,
        contacts: &mut Vec<MultiContact>,
    ) -> Result<(), SceneError> {
        let c = &self.scene.contact;
        for (i, st) in self.scene.striker.iter().enumerate() {
            masses.push(MultiMass {
                mass_kg: st.mass_kg,
                height_m: st.height_m,
                velocity_m_per_s: st.velocity_m_per_s,
            });
            let w = self.point(&format!("striker[{i}].point"), &c.object, &st.point)?;
            // a modal mallet's face is `x_j + psi . a` (its own modes, in
            // the list beside the struck object's): the struck point takes
            // `-psi` on them, as `[contact]`'s does for the hammer's mallet
            let (lower, _) = less_face(MultiEnd::Point(w), 0.0, true, self.striker_face(i)?);
            contacts.push(MultiContact {
                lower,
                upper: MultiEnd::Mass(i + 1),
                gap_m: 0.0,
                stiffness_n_per_m: st.stiffness_n_per_m,
                damping_n_s_per_m: st.damping_n_s_per_m,
            });
        }
        Ok(())
    }

    /// The face of striker `i`'s modal mallet (`psi` of its tip over the
    /// model's modes), `None` for a point-mass striker: its contact and the
    /// further pieces of its law (the expansion's touches to
    /// `End::striker`) press on its struck point less this face.
    fn striker_face(&self, i: usize) -> Result<Option<Vec<f64>>, SceneError> {
        let Some(m) = self.scene.striker.get(i).and_then(|st| st.mallet.as_ref()) else {
            return Ok(None);
        };
        let tip = m.point.as_deref().unwrap_or_default();
        Ok(Some(self.point(
            &format!("striker[{i}].mallet.point"),
            &m.object,
            tip,
        )?))
    }

    /// Each `[[touch]]`'s contact; a side on the hammer with a modal mallet
    /// (`original_mallet`: the given scene's mallet object and tip point)
    /// touches its face.
    fn push_touches(
        &self,
        original_mallet: Option<&(String, String)>,
        contacts: &mut Vec<MultiContact>,
    ) -> Result<(), SceneError> {
        let c = &self.scene.contact;
        // a modal mallet's face is `x_h + psi . a` (its modes joined to the
        // struck object's, docs/design.md "Modal mallets"): the side it
        // touches takes `-psi` on them, as `[contact]`'s point does
        let face = match (original_mallet, &c.point) {
            (Some((mallet, tip)), Some(_)) => {
                Some(self.point("hammer.point", &c.object, &format!("{mallet}.{tip}"))?)
            }
            _ => None,
        };
        // a touch's side on the hammer: its face, or a point of its modal
        // mallet (`x_h + psi_p . a`, the same form with that point's psi)
        let psi_of = |field: String, e: &SceneEnd| -> Result<Option<Vec<f64>>, SceneError> {
            match (original_mallet, &e.point) {
                (Some((mallet, _)), Some(p)) => Ok(Some(self.point(
                    &field,
                    &c.object,
                    &format!("{mallet}.{p}"),
                )?)),
                _ => Ok(face.clone()),
            }
        };
        for (i, t) in self.scene.touch.iter().enumerate() {
            let mut lower = self.side(&format!("touch[{i}].lower"), &t.lower)?;
            let mut upper = self.side(&format!("touch[{i}].upper"), &t.upper)?;
            let mut gap = t.gap_m;
            // a piece of `[contact]`'s law presses on its joined point,
            // which holds the mallet's face already
            let joined = t.lower.object == c.object && t.lower.point == c.point;
            if upper == MultiEnd::Mass(0) {
                if !joined {
                    let psi = psi_of(format!("touch[{i}].upper.point"), &t.upper)?;
                    (lower, gap) = less_face(lower, gap, true, psi);
                }
            } else if lower == MultiEnd::Mass(0) {
                let psi = psi_of(format!("touch[{i}].lower.point"), &t.lower)?;
                (upper, gap) = less_face(upper, gap, false, psi);
            } else if let Some(k) = t.upper.striker {
                // a further piece of striker k's law presses on its struck
                // point less its modal mallet's face, as the striker's own
                // contact does (`push_strikers`)
                (lower, gap) = less_face(lower, gap, true, self.striker_face(k)?);
            }
            contacts.push(MultiContact {
                lower,
                upper,
                gap_m: gap,
                stiffness_n_per_m: t.stiffness_n_per_m,
                damping_n_s_per_m: t.damping_n_s_per_m,
            });
        }
        Ok(())
    }

    /// The two channels' pickup rows (displacement, velocity) over the
    /// model's modes, from the pickups on objects in a contact (those
    /// elsewhere hear nothing).
    fn pickups(&self) -> Result<PickupRows, SceneError> {
        let n = self.n;
        let mut pickups: [(Vec<f64>, Vec<f64>); 2] =
            std::array::from_fn(|_| (vec![0.0; n], vec![0.0; n]));
        for (i, p) in self.scene.pickup.iter().enumerate() {
            let placed = self
                .scene
                .object_index(&p.object)
                .is_some_and(|o| self.first_mode[o].is_some());
            if !placed {
                continue;
            }
            let w = self.point(&format!("pickup[{i}].point"), &p.object, &p.point)?;
            let (gl, gr) = pan_gains(p.pan);
            for (ch, g) in [(0, gl), (1, gr)] {
                let row = match p.quantity {
                    Quantity::Displacement => &mut pickups[ch].0,
                    Quantity::Velocity => &mut pickups[ch].1,
                    // none in an expanded scene: each became a displacement
                    // and a velocity pickup (`Scene::expanded`)
                    Quantity::Pressure => continue,
                };
                for (r, wi) in row.iter_mut().zip(&w) {
                    *r += wi * p.gain * g;
                }
            }
        }
        Ok(pickups)
    }
}
