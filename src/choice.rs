//! Named choices: the enums of which a parameter, a YAML key or a command-line flag picks one
//! value (`mode: exact`, `--backend gpu`), each spelled once.
//!
//! An enum lists its values and names each; parsing, the "one of …" in an error and the
//! command line's possible values all come from that one list, so a name cannot differ between
//! the node's parameters, the config file and the binary's flags. The library knows no command
//! line: the binary turns a [`Choice`] into its flags' parser.

/// An enum of which a setting picks one value by name.
pub trait Choice: Copy + Sized + 'static {
    /// Every value, in the order the help and the errors list them.
    const ALL: &'static [Self];

    /// The value's name as parameters, config files and flags spell it.
    fn name(self) -> &'static str;

    /// What the value means, one line without a closing full stop (`--help` lists it beside
    /// the name); empty where the name says it all.
    fn about(self) -> &'static str {
        ""
    }

    /// The value that `text` names, if any.
    fn parse(text: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|c| c.name() == text)
    }

    /// The names, for an error: "a, b or c".
    fn names() -> String {
        let names: Vec<&str> = Self::ALL.iter().map(|c| c.name()).collect();
        match names.split_last() {
            Some((last, [])) => (*last).to_string(),
            Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
            None => String::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Choice;

    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Fruit {
        Apple,
        BloodOrange,
    }

    impl Choice for Fruit {
        const ALL: &'static [Self] = &[Fruit::Apple, Fruit::BloodOrange];
        fn name(self) -> &'static str {
            match self {
                Fruit::Apple => "apple",
                Fruit::BloodOrange => "blood-orange",
            }
        }
    }

    #[test]
    fn parses_each_name_and_lists_them() {
        assert_eq!(Fruit::parse("blood-orange"), Some(Fruit::BloodOrange));
        assert_eq!(Fruit::parse("Apple"), None);
        assert_eq!(Fruit::names(), "apple or blood-orange");
    }
}
