//! The comparison table in docs/feedback.md is the one the policies give now: a change of a
//! policy, a case or the plant that moves a row fails here until the table is regenerated
//! (`cargo bench -p crawler-policies --bench comparison`, pasted between the markers).

use crawler_policies::comparison::{in_process_table, table, CASES, POLICIES};

const BEGIN: &str = "<!-- comparison table: cargo bench -p crawler-policies --bench comparison -->";
const END: &str = "<!-- end of the comparison table -->";

#[test]
fn the_comparison_table_in_the_docs_is_what_the_policies_do_now() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/feedback.md");
    let docs = std::fs::read_to_string(&path).unwrap();
    let from = docs
        .find(BEGIN)
        .expect("docs/feedback.md has the table's first marker")
        + BEGIN.len();
    let to = docs[from..]
        .find(END)
        .expect("docs/feedback.md has the table's last marker")
        + from;
    let rows = in_process_table(&CASES, &POLICIES, None, 60.0, 2).unwrap();
    let fresh = table(&rows);
    assert_eq!(
        docs[from..to].trim(),
        fresh.trim(),
        "docs/feedback.md's comparison table is stale; the table now:\n{fresh}"
    );
}
