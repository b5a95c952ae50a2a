//! rmqtt's topic trees (subscriptions and retained messages) walked with topics far deeper than
//! the broker takes (`MAX_TOPIC_LEVELS`): every walk is a loop, so depth costs time and memory,
//! never the stack of the thread that walks (vendor/README.md).

use std::str::FromStr;

use rmqtt::retain::RetainTree;
use rmqtt::topic::Topic;
use rmqtt::trie::TopicTree;

/// Deeper than a recursion once a level survives on [`STACK`] (the red team's 6,000 levels
/// aborted a Tokio worker with 2 MiB). Not deeper: matching a `#` copies the levels that led to
/// each node, so it costs the square of the depth in time, as published.
const LEVELS: usize = 5_000;

/// The stack of the thread that walks.
const STACK: usize = 128 << 10;

fn deep(levels: usize, last: &str) -> Topic {
    let mut t = vec!["a"; levels - 1];
    t.push(last);
    Topic::from_str(&t.join("/")).expect("a topic")
}

/// Runs `f` on a thread with a small stack, as rmqtt's walks run on Tokio's workers.
fn on_small_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new()
        .stack_size(STACK)
        .spawn(f)
        .expect("a thread")
        .join()
        .expect("the walk finishes");
}

#[test]
fn the_subscription_tree_inserts_matches_removes_and_drops_a_deep_filter_without_recursion() {
    on_small_stack(|| {
        let mut tree: TopicTree<u32> = TopicTree::default();
        let filter = deep(LEVELS, "#");
        assert!(tree.insert(&filter, 1));
        assert!(tree.insert(&deep(3, "b"), 2));
        assert_eq!(tree.values_size(), 2);
        assert_eq!(tree.nodes_size(), LEVELS + 1);
        let name = deep(LEVELS + 5, "z");
        let matched: Vec<_> = tree.matches(&name).iter().flat_map(|(_, v)| v).collect();
        assert_eq!(matched, vec![&1], "the deep `#` matches a name below it");
        let other = deep(LEVELS - 5, "q");
        assert!(
            tree.matches(&other).iter().next().is_none(),
            "nor one beside it"
        );
        assert!(!tree.remove(&deep(LEVELS, "x"), &1), "no such filter");
        assert!(tree.remove(&filter, &1));
        assert_eq!(tree.nodes_size(), 3, "the emptied branch is pruned");
        assert!(tree.insert(&filter, 3));
        drop(tree);
    });
}

#[test]
fn the_retained_tree_sets_matches_expires_removes_and_drops_a_deep_topic_without_recursion() {
    on_small_stack(|| {
        let mut tree: RetainTree<u32> = RetainTree::default();
        let name = deep(LEVELS, "z");
        tree.insert(&name, 7);
        tree.insert(&deep(2, "y"), 8);
        assert_eq!(tree.values_size(), 2);
        let all = tree.matches(&Topic::from_str("#").expect("a filter"));
        assert_eq!(all.len(), 2, "`#` finds both");
        let one = tree.matches(&name);
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].1, 7);
        assert_eq!(tree.retain(usize::MAX, |v| *v != 8), 1, "one expired");
        assert_eq!(tree.values_size(), 1);
        assert_eq!(tree.nodes_size(), LEVELS, "the expired branch is pruned");
        assert_eq!(tree.remove(&name), Some(7));
        assert_eq!(tree.nodes_size(), 0);
        tree.insert(&name, 9);
        drop(tree);
    });
}
