//! SUMO additional files: the vehicle types a run uses.

use v2t_model::text::xml_escape as escape;

use std::path::Path;

use crate::SumoError;

/// A vehicle type: its id and its attributes (`length`, `maxSpeed`, `carFollowModel`, …).
pub type VType = (String, Vec<(String, String)>);

/// `<vType id="…" name="value" …/>` with the values (and the id) XML-escaped. Names must be XML
/// names (SUMO's attribute names are); [`write_additional`] checks them.
pub fn vtype_xml(id: &str, attributes: &[(String, String)]) -> String {
    let mut xml = format!("<vType id=\"{}\"", escape(id));
    for (name, value) in attributes {
        xml.push_str(&format!(" {name}=\"{}\"", escape(value)));
    }
    xml.push_str("/>");
    xml
}

/// The text of an additional file with one `<vType>` per entry of `vtypes`; fails on an attribute
/// name that is not an XML name.
pub fn additional_xml(vtypes: &[VType]) -> Result<String, SumoError> {
    let mut xml = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<additional>\n");
    for (id, attributes) in vtypes {
        if let Some((name, _)) = attributes.iter().find(|(name, _)| !is_xml_name(name)) {
            return Err(SumoError::InvalidArgument {
                what: "vType attribute name",
                problem: format!("`{name}` of vType `{id}` is not an XML name"),
            });
        }
        xml.push_str("    ");
        xml.push_str(&vtype_xml(id, attributes));
        xml.push('\n');
    }
    xml.push_str("</additional>\n");
    Ok(xml)
}

/// Writes [`additional_xml`] of `vtypes` to `path`.
pub fn write_additional(path: &Path, vtypes: &[VType]) -> Result<(), SumoError> {
    let xml = additional_xml(vtypes)?;
    std::fs::write(path, xml).map_err(SumoError::io(format!("writing {}", path.display())))
}

fn is_xml_name(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_' || c == ':')
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | ':' | '-' | '.'))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn attrs(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
        pairs.iter().map(|(k, v)| ((*k).to_owned(), (*v).to_owned())).collect()
    }

    #[test]
    fn values_are_escaped() {
        let xml = vtype_xml("a\"b", &attrs(&[("length", "4.5"), ("name", "<x & 'y'>\n")]));
        assert_eq!(xml, "<vType id=\"a&quot;b\" length=\"4.5\" name=\"&lt;x &amp; &#39;y&#39;&gt;&#10;\"/>");
        let doc = roxmltree::Document::parse(&xml).unwrap();
        assert_eq!(doc.root_element().attribute("name"), Some("<x & 'y'>\n"));
        assert_eq!(doc.root_element().attribute("id"), Some("a\"b"));
    }

    #[test]
    fn the_file_holds_every_type_and_refuses_bad_names() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.add.xml");
        let types = vec![
            ("vut".to_owned(), attrs(&[("length", "4.8"), ("maxSpeed", "20")])),
            ("bv".to_owned(), attrs(&[("vClass", "passenger")])),
        ];
        write_additional(&path, &types).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap();
        let ids: Vec<_> =
            doc.descendants().filter(|n| n.has_tag_name("vType")).filter_map(|n| n.attribute("id")).collect();
        assert_eq!(ids, ["vut", "bv"]);
        let bad = vec![("x".to_owned(), attrs(&[("max speed", "1")]))];
        assert!(matches!(write_additional(&path, &bad), Err(SumoError::InvalidArgument { .. })));
    }
}
