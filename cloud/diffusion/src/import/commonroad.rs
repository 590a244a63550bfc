//! CommonRoad XML (2020a) dynamic obstacles.
