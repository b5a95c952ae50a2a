//! What online change needs to know about a chart's net: its networks, and the places it can
//! mark.

use cetratus_net::Net;

/// Per place of `new`: true when no place of its network (its connected part, through
/// transitions) is a place of `old` by id.
pub(super) fn networks_without_kept_places(new: &Net, old: &Net) -> Vec<bool> {
    let n = new.num_places();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for t in 0..new.num_transitions() {
        let t = cetratus_net::TransIdx(t as u32);
        let mut first: Option<usize> = None;
        for p in new
            .pre(t)
            .iter()
            .map(|&(p, _)| p)
            .chain(new.post(t).iter().map(|&(p, _)| p))
        {
            let p = p.index();
            match first {
                None => first = Some(p),
                Some(f) => {
                    let (a, b) = (find(&mut parent, f), find(&mut parent, p));
                    parent[a] = b;
                }
            }
        }
    }
    let mut kept = vec![false; n];
    for (i, p) in new.places().iter().enumerate() {
        if old.place_by_id(&p.id).is_some() {
            let r = find(&mut parent, i);
            kept[r] = true;
        }
    }
    (0..n).map(|i| !kept[find(&mut parent, i)]).collect()
}

/// The places a net lets be marked, guards ignored: those marked at M0, and the outputs of every
/// transition whose input places can all be marked (a fixpoint, linear in the net). For a net
/// without inhibitor arcs this contains every place marked in some reachable marking.
pub fn markable_places(net: &Net) -> Vec<bool> {
    let mut markable: Vec<bool> = net.places().iter().map(|p| p.initial > 0).collect();
    let mut changed = true;
    while changed {
        changed = false;
        for t in 0..net.num_transitions() {
            let t = cetratus_net::TransIdx(t as u32);
            if net.pre(t).iter().all(|&(p, _)| markable[p.index()]) {
                for &(p, _) in net.post(t) {
                    if !markable[p.index()] {
                        markable[p.index()] = true;
                        changed = true;
                    }
                }
            }
        }
    }
    markable
}
