//! Where a path enters a junction: the line a vehicle that gives way waits before.
//!
//! A point is in a junction when it lies on one of the junction's drivable connecting lanes (the
//! lane surfaces of the drivable area, [`crate::drivable`]). Connecting lanes cover the junction's
//! whole area between its incoming roads, so the first point of a path on them is where the path
//! crosses the junction's edge on its lane: the stop line of a driver who waits outside.

use v2t_model::geometry::Point2;
use v2t_model::path::ReferencePath;

use crate::Map;

/// Step of the scan back along a path, m (refined by bisection afterwards).
const SCAN_STEP_M: f64 = 0.25;
/// How exactly the entry is located, m.
const ENTRY_TOLERANCE_M: f64 = 0.01;

impl Map {
    /// The junction whose drivable connecting lanes hold `q`, if any; the first one found where
    /// junctions overlap.
    pub fn junction_at(&self, q: Point2) -> Option<&str> {
        self.graph
            .lanes
            .iter()
            .filter(|l| l.drivable)
            .filter_map(|l| Some((l, l.junction.as_deref()?)))
            .find(|(l, _)| crate::drivable::lane_quads(l).any(|quad| crate::drivable::inside(q, &quad)))
            .map(|(_, j)| j)
    }

    /// Where `path` enters the junction it is in at arc length `at_s_m`: the least arc length from
    /// which the path stays in that junction up to `at_s_m` (within 1 cm); 0 when the path starts
    /// in it. `None` when the path is not in a junction at `at_s_m`.
    pub fn junction_entry(&self, path: &ReferencePath, at_s_m: f64) -> Option<f64> {
        let at = at_s_m.clamp(0.0, path.length());
        let junction = self.junction_at(path.point_at(at))?;
        let inside = |s: f64| self.junction_at(path.point_at(s)) == Some(junction);
        let mut last_in = at;
        loop {
            let s = last_in - SCAN_STEP_M;
            if s < 0.0 {
                return Some(if inside(0.0) { 0.0 } else { self.bisect(&inside, 0.0, last_in) });
            }
            if !inside(s) {
                return Some(self.bisect(&inside, s, last_in));
            }
            last_in = s;
        }
    }

    /// The boundary between `out` (not inside) and `inn` (inside), within [`ENTRY_TOLERANCE_M`].
    fn bisect(&self, inside: &dyn Fn(f64) -> bool, mut out: f64, mut inn: f64) -> f64 {
        while inn - out > ENTRY_TOLERANCE_M {
            let mid = 0.5 * (out + inn);
            if inside(mid) {
                inn = mid;
            } else {
                out = mid;
            }
        }
        inn
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use v2t_model::path::PathBuilder;

    /// One road of 50 m ending at junction 7, whose one connecting road goes on straight for 20 m,
    /// then another road of 50 m.
    fn map() -> Map {
        let road = |id: &str, x0: f64, len: f64, junction: &str| {
            format!(
                r#"<road id="{id}" length="{len}" junction="{junction}">
                <planView><geometry s="0" x="{x0}" y="0" hdg="0" length="{len}"><line/></geometry></planView>
                <lanes><laneSection s="0"><center><lane id="0" type="none"/></center>
                <right><lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
                </laneSection></lanes></road>"#
            )
        };
        let xml = format!(
            r#"<OpenDRIVE><header revMajor="1" revMinor="6"/>{}{}{}
            <junction id="7"><connection id="0" incomingRoad="1" connectingRoad="2" contactPoint="start">
            <laneLink from="-1" to="-1"/></connection></junction></OpenDRIVE>"#,
            road("1", 0.0, 50.0, "-1"),
            road("2", 50.0, 20.0, "7"),
            road("3", 70.0, 50.0, "-1")
        );
        Map::parse(&xml, "t").unwrap()
    }

    #[test]
    fn a_path_enters_the_junction_where_its_connecting_lane_begins() {
        let m = map();
        // The lane's centre is y = -1.75; the path runs on it from x = 10.
        let path = PathBuilder::new(10.0, -1.75, 0.0).line(100.0).build(0.5).unwrap();
        assert_eq!(m.junction_at(Point2 { x: 60.0, y: -1.75 }), Some("7"));
        assert_eq!(m.junction_at(Point2 { x: 60.0, y: -4.0 }), None, "outside the lane's width");
        assert_eq!(m.junction_at(Point2 { x: 30.0, y: -1.75 }), None);
        let entry = m.junction_entry(&path, 55.0).unwrap();
        assert!((entry - 40.0).abs() <= 0.02, "{entry}");
        assert_eq!(m.junction_entry(&path, 20.0), None, "not in a junction there");
        // A path that starts inside enters at 0.
        let inside = PathBuilder::new(55.0, -1.75, 0.0).line(30.0).build(0.5).unwrap();
        assert_eq!(m.junction_entry(&inside, 5.0), Some(0.0));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Wherever a path starts on the lane before the junction, and wherever inside the
        /// junction it is asked from, the entry is the junction's edge (x = 50), within 2 cm, and
        /// every point after it up to the asking point lies in the junction.
        #[test]
        fn the_entry_is_the_edge_wherever_the_path_starts(start in 0.0f64..45.0, inside in 0.5f64..19.5, lateral in -1.5f64..1.5) {
            let m = map();
            let path = PathBuilder::new(start, -1.75 + lateral, 0.0).line(100.0).build(0.25).unwrap();
            let at = 50.0 - start + inside;
            let entry = m.junction_entry(&path, at).unwrap();
            proptest::prop_assert!((entry - (50.0 - start)).abs() <= 0.02, "entry {} for a start at {}", entry, start);
            let mut s = entry;
            while s <= at {
                proptest::prop_assert_eq!(m.junction_at(path.point_at(s)), Some("7"));
                s += 0.5;
            }
        }
    }
}
